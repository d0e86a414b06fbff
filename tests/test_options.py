"""``bidegree.options.Options``: the one place settings become arguments (issue 15)."""

from __future__ import annotations

import argparse
import dataclasses

import bidegree
import numpy as np
import pytest
from bidegree.options import Options
from cages import cube


def test_bad_values_are_typed_errors() -> None:
    for kwargs, word in (
        ({"degree": "x"}, "degree"),
        ({"degree": 2.5}, "degree"),
        ({"levels": True}, "levels"),
        ({"rules": "fancy"}, "rules"),
        ({"output": None}, "output"),
        ({"boundary": "smooth"}, "boundary"),
        ({"creasing": 1}, "creasing"),
        ({"limit": "yes"}, "limit"),
        ({"tolerance": -1.0}, "tolerance"),
        ({"tolerance": float("nan")}, "tolerance"),
        ({"tolerance": "small"}, "tolerance"),
        ({"memory_budget": -5}, "memory_budget"),
    ):
        with pytest.raises(bidegree.InvalidInputError, match=word):
            Options(**kwargs)
    # Range checks stay the core's, with its typed errors, when a request is made.
    with pytest.raises(bidegree.DegreeOutOfRangeError):
        Options(degree=0).plan(cube())
    with pytest.raises(bidegree.LevelOutOfRangeError):
        Options(levels=99).subdivide(cube())


def test_numpy_values_are_accepted() -> None:
    options = Options(degree=np.int64(3), levels=np.int32(2), limit=np.bool_(True))
    assert options == Options(degree=3, levels=2, limit=True)
    assert type(options.degree) is int and type(options.limit) is bool


@pytest.mark.parametrize(
    "options",
    [
        Options(degree=3, levels=2, rules="classic", creasing="chaikin", limit=True),
        Options(degree=4, levels=1, limit=True, normals=True),
        Options(degree=4, levels=2, normals=True),
        Options(degree=2, levels=2, output="dual"),
    ],
    ids=["classic-limit", "limit-normals", "normals", "dual"],
)
def test_every_field_reaches_the_request(options: Options) -> None:
    """plan + evaluate and subdivide give exactly what the full keyword call gives."""
    mesh = cube()
    direct = bidegree.subdivide(
        mesh,
        degree=options.degree,
        levels=options.levels,
        output=options.output,
        memory_budget=options.memory_budget,
        rules=options.rules,
        creasing=options.creasing,
        limit=options.limit,
        normals=options.normals,
    )
    result = options.subdivide(mesh)
    np.testing.assert_array_equal(result.points, direct.points)
    assert (result.normals is None) == (direct.normals is None)
    if direct.normals is not None:
        np.testing.assert_array_equal(result.normals, direct.normals)
    plan = options.plan(mesh)
    points, normals = options.evaluate(plan, mesh.points)
    np.testing.assert_array_equal(points, direct.points)
    assert (normals is None) == (direct.normals is None)


def test_memory_budget_and_adaptive_reach_the_request() -> None:
    with pytest.raises(bidegree.MemoryBudgetError):
        Options(levels=6, memory_budget=1 << 16).subdivide(cube())
    with pytest.raises(bidegree.MemoryBudgetError):
        Options(levels=6, memory_budget=1 << 16).plan(cube())
    options = Options(degree=3, levels=4, adaptive=True, tolerance=0.02)
    got = options.subdivide_adaptive(cube())
    want = bidegree.subdivide_adaptive(cube(), degree=3, max_level=4, tolerance=0.02)
    np.testing.assert_array_equal(got.triangles, want.triangles)
    with pytest.raises(bidegree.InvalidInputError, match="limit normals"):
        Options(adaptive=True, normals=True).subdivide_adaptive(cube())
    assert Options(rules="classic", output="dual").unsupported_by_adaptive() == [
        "classic rules",
        "the dual output",
    ]


def test_has_limit_positions_is_what_the_core_gives() -> None:
    for output in ("primal", "dual"):
        for rules, degrees in (("averaging", (1, 2, 3, 4)), ("classic", (1, 2, 3))):
            for degree in degrees:
                for levels in (0, 1):
                    options = Options(
                        degree=degree, levels=levels, output=output, rules=rules, limit=True
                    )
                    try:
                        options.subdivide(cube())
                        given = True
                    except bidegree.InvalidInputError:
                        given = False
                    assert options.has_limit_positions() == given, options


def test_from_namespace_takes_every_field_the_cli_has() -> None:
    from bidegree import cli

    parser = cli.build_parser()
    args = parser.parse_args(
        [
            "subdivide",
            "in.obj",
            "-o",
            "out.obj",
            "--degree",
            "3",
            "--levels",
            "1",
            "--rules",
            "classic",
            "--limit",
            "--memory-budget",
            "2M",
            "--output",
            "dual",
        ]
    )
    options = Options.from_namespace(args)
    assert options == Options(
        degree=3, levels=1, rules="classic", limit=True, memory_budget=2 << 20, output="dual"
    )
    adaptive = Options.from_namespace(
        parser.parse_args(
            [
                "subdivide",
                "in.obj",
                "-o",
                "o.obj",
                "--adaptive",
                "--max-level",
                "5",
                "--tolerance",
                "0.01",
            ]
        )
    )
    assert (adaptive.adaptive, adaptive.levels, adaptive.tolerance) == (True, 5, 0.01)
    # Every field of Options is either read from the CLI or deliberately left to its default.
    names = {f.name for f in dataclasses.fields(Options)}
    assert names - set(vars(args)) <= {"creasing", "use_creases"}
    assert Options.from_namespace(argparse.Namespace()) == Options()
