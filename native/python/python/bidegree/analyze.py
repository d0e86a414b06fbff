"""``bidegree analyze``: the paper's §4 analysis of one degree at one valence.

Everything is computed from the engine (``bidegree._native.analyze``): the subdivision matrix of
the invariant neighbourhood of an irregular vertex (odd degrees) or face (even degrees), its
Fourier blocks and their eigenvalues, and the C1 checks of Zorin & Schröder §4.3-4.4 (leading
spectrum, characteristic map regular with winding number one), plus the C2 obstruction
(third eigenvalue above the square of the subdominant one).

``--plot DIR`` writes pictures in the spirit of the paper's figures:

- ``eigenvalues.png`` (Fig. 17): eigenvalue magnitudes of the Fourier blocks against
  ``c = cos(theta)`` for degrees 2..9, log scale. The curves come from the blocks' symbol
  ``B(theta) = sum_d L_d exp(i d theta)``, whose coefficients ``L_d`` are read off the engine's
  matrix at a valence large enough for the stencils not to wrap around (the part of the matrix
  that is the same for all sectors, which only mode 0 sees, is removed); the dots are the actual
  blocks of the requested valence;
- ``subdominant.png`` (Fig. 18): the subdominant eigenvalue against the valence for degrees 2..9
  with the conjectured limit ``2^(-4/k)``;
- ``characteristic_map.png`` (Fig. 20-21): the refined control net of the characteristic map, all
  sectors, with one sector and the ring the checks use highlighted;
- ``jacobian.png`` (Fig. 22): the Jacobian of the characteristic map over one sector, and its
  bounds on the ring against the valence for the requested degree;
- ``basis.png`` (Fig. 8): basis functions near an irregular point of valence 9 for
  degrees 2..9 (a unit impulse at the centre, or at a face of the central k-gon for even
  degrees, subdivided a few levels), as height fields.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

import numpy as np

#: Degrees the paper analyses.
PAPER_DEGREES = tuple(range(2, 10))


def neighbourhood_size(degree: int) -> int:
    """``N``: the minimal invariant neighbourhood has ``N`` rings (the complete one ``N + 1``)."""
    return degree // 2 if degree % 2 == 0 else (degree - 1) // 2


def analyze(degree: int, valence: int, steps: int = 4) -> dict[str, Any]:
    """The analysis dict of :func:`bidegree._native.analyze` (``steps = 0``: no report)."""
    from bidegree import _native

    return _native.analyze(degree, valence, steps)


class Symbol:
    """The Fourier symbol of a degree: ``B(theta) = sum_d L_d exp(i d theta)``.

    ``B(2 pi m / k)`` is the Fourier block of mode ``m != 0`` at every valence ``k``: the
    averaging rules are the same around every irregular point except through the centre, whose
    contributions are the same for all sectors and so only reach mode 0.
    """

    def __init__(self, degree: int) -> None:
        self.degree = degree
        n = neighbourhood_size(degree)
        # The stencils reach N sectors either way: a valence of 2N + 4 leaves sectors in between.
        k = max(2 * n + 4, 8)
        result = analyze(degree, k, steps=0)
        matrix = result["matrix"]
        off = 1 if degree % 2 == 1 else 0
        p = (matrix.shape[0] - off) // k
        blocks = [matrix[off : off + p, off + d * p : off + (d + 1) * p] for d in range(k)]
        common = blocks[k // 2]
        self.terms: dict[int, np.ndarray] = {}
        for d, block in enumerate(blocks):
            local = block - common
            if np.abs(local).max() > 1e-15:
                self.terms[d if d <= k // 2 else d - k] = local
        self.size = p

    def block(self, theta: float) -> np.ndarray:
        """``B(theta)``."""
        b = np.zeros((self.size, self.size), dtype=complex)
        for d, term in self.terms.items():
            b += term * np.exp(1j * d * theta)
        return b

    def eigenvalues(self, theta: float) -> np.ndarray:
        """Eigenvalues of ``B(theta)`` by decreasing modulus."""
        values = np.linalg.eigvals(self.block(theta))
        return values[np.argsort(-np.abs(values))]

    def subdominant(self, valence: int) -> float:
        """The subdominant eigenvalue at a valence (mode 1's leading eigenvalue)."""
        return float(np.abs(self.eigenvalues(2 * np.pi / valence)[0]))


# ---------------------------------------------------------------------------------------------
# Pictures


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update(
        {
            "font.size": 9,
            "axes.titlesize": 10,
            "axes.spines.top": False,
            "axes.spines.right": False,
            "savefig.dpi": 130,
        }
    )
    return plt


def _degree_colors(plt: Any) -> dict[int, Any]:
    cmap = plt.get_cmap("viridis")
    return {d: cmap((d - 2) / 7 * 0.9) for d in PAPER_DEGREES}


def plot_eigenvalues(
    path: str, symbols: dict[int, Symbol], result: dict[str, Any], plt: Any
) -> None:
    """Fig. 17: block eigenvalue magnitudes against ``c = cos(theta)``, log scale."""
    degree, valence = result["degree"], result["valence"]
    fig, axes = plt.subplots(2, 4, figsize=(13, 6.4), sharex=True, sharey=True)
    thetas = np.linspace(1e-3, np.pi, 361)
    floor = 2.0**-14
    for ax, (d, symbol) in zip(axes.flat, symbols.items(), strict=True):
        values = np.array([np.abs(symbol.eigenvalues(t)) for t in thetas])
        c = np.cos(thetas)
        for j in range(1, 15):
            ax.axhline(2.0**-j, color="0.9", lw=0.6, zorder=0)
        for column in range(values.shape[1]):
            ys = values[:, column]
            if ys.max() < floor:
                continue
            ax.plot(
                c, ys, color="tab:blue" if column == 0 else "0.45", lw=1.3 if column == 0 else 0.7
            )
        # The blocks of the requested valence (mode 0 with its eigenvalue 1 at c = 1).
        if d == degree:
            for m, block_values in enumerate(result["block_eigenvalues"]):
                mags = np.abs(block_values)
                mags = mags[mags > floor]
                cm = np.cos(2 * np.pi * m / valence)
                ax.plot(np.full(mags.shape, cm), mags, "o", ms=3.5, color="tab:orange", zorder=3)
            ax.set_title(f"degree {d} (dots: blocks of valence {valence})")
        else:
            ax.set_title(f"degree {d}")
        ax.set_yscale("log", base=2)
        ax.set_ylim(floor, 1.3)
        ax.set_xlim(-1, 1)
    for ax in axes[-1]:
        ax.set_xlabel("c = cos(2 pi m / k)")
    for ax in axes[:, 0]:
        ax.set_ylabel("|eigenvalue|")
    fig.suptitle(
        "Eigenvalue magnitudes of the Fourier blocks B(c) (leading one in blue; grid lines at 2^-j)"
    )
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_subdominant(
    path: str, symbols: dict[int, Symbol], result: dict[str, Any], plt: Any
) -> None:
    """Fig. 18: subdominant eigenvalue against the valence, with the limit ``2^(-4/k)``."""
    colors = _degree_colors(plt)
    valences = np.arange(3, 41)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.4), sharey=True)
    for ax, parity, name in ((axes[0], 1, "primal (odd degrees)"), (axes[1], 0, "dual (even)")):
        limit = 2.0 ** (-4.0 / valences)
        ax.plot(valences, limit, color="0.6", lw=4, alpha=0.5, label="2^(-4/k) (conjectured limit)")
        for d, symbol in symbols.items():
            if d % 2 != parity:
                continue
            mu = [symbol.subdominant(int(k)) for k in valences]
            ax.plot(valences, mu, "-o", ms=2.5, lw=1.2, color=colors[d], label=f"degree {d}")
        if result["degree"] % 2 == parity:
            mu = abs(result["block_eigenvalues"][1][0])
            ax.plot([result["valence"]], [mu], "*", ms=12, color="tab:red", zorder=4)
            ax.annotate(
                f"degree {result['degree']}, k = {result['valence']}: {mu:.6f}",
                (result["valence"], mu),
                xytext=(12, -18),
                textcoords="offset points",
                fontsize=8,
            )
        ax.set_title(f"Subdominant eigenvalue, {name}")
        ax.set_xlabel("valence k")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    axes[0].set_ylabel("lambda1")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def _ring_curves(params: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Index paths (rows, columns) of the ring's inner and outer boundaries in one sector: along
    the row at ``u = level`` then back down the column at ``v = level``."""
    us, vs = params[:, 0, 0], params[0, :, 1]
    curves = []
    for level in (0.5, 1.0):
        r0 = int(np.argmin(np.abs(us - level)))
        c0 = int(np.argmin(np.abs(vs - level)))
        rows = np.concatenate([np.full(c0 + 1, r0), np.arange(r0 - 1, -1, -1)])
        columns = np.concatenate([np.arange(c0 + 1), np.full(r0, c0)])
        curves.append((rows, columns))
    return curves


def plot_characteristic_map(path: str, result: dict[str, Any], plt: Any) -> None:
    """Fig. 20-21: the refined control net of the characteristic map, and one sector of the ring
    with its cells coloured by the Jacobian."""
    from matplotlib.collections import PolyCollection

    points = result["map_points"]  # (k, rows, columns, 2)
    params = result["map_params"]
    k = points.shape[0]
    fig, axes = plt.subplots(1, 2, figsize=(13, 6.2))
    ax = axes[0]
    for s in range(k):
        net = points[s]
        color, lw = ("tab:blue", 0.6) if s == 0 else ("0.6", 0.35)
        for r in range(net.shape[0]):
            ax.plot(net[r, :, 0], net[r, :, 1], color=color, lw=lw)
        for c in range(net.shape[1]):
            ax.plot(net[:, c, 0], net[:, c, 1], color=color, lw=lw)
        for (rows, columns), style in zip(_ring_curves(params), ("--", "-"), strict=True):
            ax.plot(*net[rows, columns].T, style, color="tab:red", lw=1.4)
    ax.plot([0], [0], "k+", ms=12, mew=1.5)
    ax.set_aspect("equal")
    ax.set_title(
        f"Characteristic map, degree {result['degree']}, valence {k}: control net after "
        f"{result['map_steps']} steps\n(sector 0 in blue; the ring 1/2 <= max(u, v) <= 1 "
        "between the red curves)"
    )
    ax.set_xticks([])
    ax.set_yticks([])
    for side in ("left", "bottom"):
        ax.spines[side].set_visible(False)
    ax = axes[1]
    net = points[0]
    jac = result["map_cell_jacobian"][..., 0]
    ring = result["map_in_ring"]
    quads, colors = [], []
    for r, c in zip(*np.nonzero(ring), strict=True):
        quads.append([net[r, c], net[r + 1, c], net[r + 1, c + 1], net[r, c + 1]])
        colors.append(jac[r, c])
    cells = PolyCollection(quads, array=np.array(colors), cmap="viridis", edgecolors="white")
    cells.set_linewidth(0.4)
    ax.add_collection(cells)
    fig.colorbar(
        cells,
        ax=ax,
        orientation="horizontal",
        shrink=0.7,
        pad=0.1,
        label="Jacobian (smallest corner value per cell)",
    )
    ax.plot([0], [0], "k+", ms=12, mew=1.5)
    ax.autoscale_view()
    ax.set_aspect("equal")
    ax.set_title(
        f"One sector of the ring (Fig. 20c): Jacobian in [{result['jacobian_min']:.4f}, "
        f"{result['jacobian_max']:.4f}],\nwinding number {result['winding']}: "
        f"C1 {'yes' if result['c1'] else 'no'}"
    )
    ax.grid(alpha=0.25)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_jacobian(path: str, result: dict[str, Any], sweep: list[dict[str, Any]], plt: Any) -> None:
    """Fig. 22: the Jacobian over one sector and its bounds on the ring against the valence."""
    params = result["map_params"]
    cells = result["map_cell_jacobian"][..., 0]
    ring = result["map_in_ring"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 5), gridspec_kw={"width_ratios": [1.1, 1]})
    ax = axes[0]
    # Cells lie between grid positions: their edges are the positions themselves.
    u = params[:, 0, 0]
    v = params[0, :, 1]
    shown = np.where(ring, cells, np.nan)
    mesh = ax.pcolormesh(v, u, shown, cmap="viridis", shading="flat")
    ax.pcolormesh(v, u, np.where(ring, np.nan, cells), cmap="Greys", alpha=0.35, shading="flat")
    fig.colorbar(mesh, ax=ax, label="Jacobian det d(x,y)/d(u,v) (smallest corner value per cell)")
    ax.set_aspect("equal")
    ax.set_xlabel("v (along the sector's second edge)")
    ax.set_ylabel("u (along the first edge)")
    ax.set_title(
        f"Degree {result['degree']}, valence {result['valence']}: Jacobian on the ring\n"
        f"min {result['jacobian_min']:.4f}, max {result['jacobian_max']:.4f} (grey: outside)"
    )
    ax = axes[1]
    ks = [r["valence"] for r in sweep]
    lo = [r["jacobian_min"] for r in sweep]
    hi = [r["jacobian_max"] for r in sweep]
    ax.fill_between(ks, lo, hi, color="tab:blue", alpha=0.15)
    ax.plot(ks, hi, "-o", ms=3, color="tab:blue", label="largest")
    ax.plot(ks, lo, "-o", ms=3, color="tab:green", label="smallest")
    ax.axhline(0, color="0.3", lw=0.8)
    if min(lo) > 0:
        from matplotlib.ticker import FuncFormatter

        ax.set_yscale("log")
        plain = FuncFormatter(lambda y, _: f"{y:g}")
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(plain)
    else:
        ax.set_yscale("symlog", linthresh=0.05)
    ax.set_xlabel("valence k")
    ax.set_ylabel("Jacobian on the ring")
    c1 = all(r["c1"] for r in sweep)
    ax.set_title(
        f"Degree {result['degree']}: Jacobian bounds against the valence "
        f"(C1 {'at every valence' if c1 else 'NOT at every valence'})"
    )
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def basis_surface(degree: int, valence: int, steps: int) -> tuple[np.ndarray, np.ndarray]:
    """Points ``(x, y, z)`` of a basis function near an irregular point (the centre of a primal
    scheme, a face of the k-gon of a dual one) and a triangulation of them.

    Sector ``s`` (the quadrant ``u, v >= 0``, ``w = u + i v``) is laid out on the plane by the
    conformal map ``w -> w^(4/k) exp(2 pi i s / k)`` of the paper's §4.5, which closes the
    sectors up around the centre without kinks and maps the points that two sectors share (the
    primal edge, the dual strip taken from the next sector) to the same place.
    """
    import matplotlib.tri as mtri

    from bidegree import _native

    net = _native.basis_function(degree, valence, steps)
    params, values = net["params"].reshape(-1, 2), net["values"]
    w = params[:, 0] + 1j * params[:, 1]
    xs, ys, zs = [], [], []
    for s in range(valence):
        z = w ** (4.0 / valence) * np.exp(2j * np.pi * s / valence)
        xs.append(z.real)
        ys.append(z.imag)
        zs.append(values[s].reshape(-1))
    if not net["primal"]:
        # The centre of the dual k-gon, drawn at the average of the k faces around it (the
        # value the next averaging gives it), so the triangulation does not bridge the hole.
        first = values[:, 1, 0]  # faces (s, 0, 0), row 1 of each sector
        xs.append(np.zeros(1))
        ys.append(np.zeros(1))
        zs.append(np.array([first.mean()]))
    x, y, z = (np.concatenate(a) for a in (xs, ys, zs))
    xy = np.round(np.stack([x, y], 1), 9)
    _, unique = np.unique(xy, axis=0, return_index=True)
    x, y, z = x[unique], y[unique], z[unique]
    return np.stack([x, y, z], 1), mtri.Triangulation(x, y).triangles


def plot_basis(path: str, plt: Any, valence: int = 9, steps: int = 3) -> None:
    """Fig. 8: basis functions near an irregular point, degrees 2..9, as height fields."""
    from matplotlib.colors import LightSource

    fig = plt.figure(figsize=(14, 7.2))
    light = LightSource(azdeg=315, altdeg=35)
    for index, d in enumerate(PAPER_DEGREES):
        points, triangles = basis_surface(d, valence, steps)
        z = points[:, 2]
        # Crop to the support (plus a margin) so the bump fills the panel.
        keep_points = np.abs(z) > 2e-3 * np.abs(z).max()
        radius = 1.05 * np.hypot(points[keep_points, 0], points[keep_points, 1]).max()
        inside = np.hypot(points[:, 0], points[:, 1]) <= radius
        tri_keep = inside[triangles].all(axis=1)
        ax = fig.add_subplot(2, 4, index + 1, projection="3d")
        ax.plot_trisurf(
            points[:, 0],
            points[:, 1],
            z / z.max(),
            triangles=triangles[tri_keep],
            cmap="plasma",
            lightsource=light,
            linewidth=0,
            antialiased=False,
        )
        ax.set_title(
            f"degree {d}" + (" (primal: centre vertex)" if d % 2 else " (dual: k-gon face)")
        )
        ax.set_box_aspect((1, 1, 0.6), zoom=1.6)
        ax.view_init(elev=30, azim=-62)
        ax.set_axis_off()
    fig.suptitle(
        f"Basis functions near an irregular point of valence {valence} "
        f"(a unit impulse subdivided {steps + 1} levels, height scaled to 1; sectors laid out "
        "by w -> w^(4/k))"
    )
    fig.subplots_adjust(left=0, right=1, bottom=0, top=0.91, wspace=0, hspace=0.06)
    fig.savefig(path)
    plt.close(fig)


def write_plots(directory: str, result: dict[str, Any], steps: int) -> list[str]:
    """Writes the pictures into ``directory``; returns their paths."""
    plt = _pyplot()
    os.makedirs(directory, exist_ok=True)
    symbols = {d: Symbol(d) for d in PAPER_DEGREES}
    paths = []

    def out(name: str) -> str:
        paths.append(os.path.join(directory, name))
        return paths[-1]

    plot_eigenvalues(out("eigenvalues.png"), symbols, result, plt)
    plot_subdominant(out("subdominant.png"), symbols, result, plt)
    plot_characteristic_map(out("characteristic_map.png"), result, plt)
    sweep = [
        result if k == result["valence"] else analyze(result["degree"], k, steps)
        for k in range(3, 17)
    ]
    plot_jacobian(out("jacobian.png"), result, sweep, plt)
    plot_basis(out("basis.png"), plt)
    return paths


# ---------------------------------------------------------------------------------------------
# Command line


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``bidegree analyze``."""
    parser.description = (
        "The paper's §4 analysis of one degree at one valence: subdivision matrix, Fourier "
        "blocks and eigenvalues, C1 checks (characteristic map) and the C2 obstruction."
    )
    parser.add_argument("--degree", type=int, default=4, help="degree, 1..31 (default 4)")
    parser.add_argument("--valence", type=int, default=5, help="valence, >= 3 (default 5)")
    parser.add_argument(
        "--steps",
        type=int,
        default=4,
        help="engine steps refining the characteristic map (default 4: spacing 1/16)",
    )
    parser.add_argument("--plot", metavar="DIR", help="write PNG pictures into DIR")


def run(args: argparse.Namespace) -> int:
    """Run ``bidegree analyze``; returns the exit status."""
    import bidegree

    try:
        if args.degree < 2:
            raise bidegree.InvalidInputError("the analysis needs degree >= 2")
        if args.plot and os.path.exists(args.plot) and not os.path.isdir(args.plot):
            raise bidegree.BidegreeIOError(f"{args.plot}: not a directory")
        if not 1 <= args.steps <= 8:
            raise bidegree.InvalidInputError("--steps must be in 1..8")
        result = analyze(args.degree, args.valence, args.steps)
        print(result["text"])
        values = result["eigenvalues"]
        modes = result["modes"]
        shown = ", ".join(
            f"{abs(z):.6f} (m={m})" for z, m in zip(values[:8], modes[:8], strict=True)
        )
        print(f"leading |eigenvalues| (of {len(values)}): {shown}")
        if args.plot:
            for path in write_plots(args.plot, result, args.steps):
                print(f"wrote {path}")
    except (bidegree.BidegreeError, ValueError, OSError) as exc:
        print(f"bidegree analyze: error: {exc}", file=sys.stderr)
        return 1
    return 0
