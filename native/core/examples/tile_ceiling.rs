//! Research driver (issue 16, not library code): the ceiling of cached evaluation by tiles.
//! Findings and the measured table: `docs/research/tile-evaluation.md`.
//!
//! Over a regular region the averaging rules are the tensor-product B-spline of their degree,
//! so the points of levels `1..=L` over one cage face follow from the face's `(n + 1) x (n + 1)`
//! net alone, by separable 1-D steps (replication and `n` averages, as two phase masks) on
//! arrays that stay in the first-level cache, with nothing read from memory but the net and
//! nothing written but the last level. This driver measures that work against a cached
//! [`Plan::evaluate`] of the same degree and level on the callgrind driver's 3,840-quad
//! ico-quad sphere: one tile per cage face, the tiles' nets gathered from the cage's points
//! through a table (as a plan's would be), the last level's `2^L x 2^L` points of each tile
//! written either in tile order (an output numbered by cage face) or through a table into a
//! permutation of the output (the cost of keeping the present numbering). It is a ceiling: the
//! irregular vertices' neighbourhoods, which the sphere has (32 of them), creases and the
//! classification are not modelled, every face is taken as regular, and the nets are synthetic
//! (the values are not the plan's; the work is). `tile_ceiling verify` checks the tiles' values
//! where the nets are real: on a 16 x 16 torus at degree 3, level 3, every tile point is one of
//! the plan's (to 4.8e-7 in f32; wrong masks fail it).
//!
//! ```sh
//! cargo run --release -p bidegree --example tile_ceiling -- [LEVEL] [REPS]
//! # instructions of one tiled evaluation, one thread (Ir(2 reps) - Ir(1 rep)):
//! valgrind --tool=callgrind target/release/examples/tile_ceiling tiles-[scatter-]D-L REPS
//! ```
//!
//! Degrees 3, 4 and 9; the processor must have AVX2 (the tiles are compiled for it, as the
//! library's kernels are where it has them).

use std::hint::black_box;
use std::time::Instant;

use bidegree::{Options, Plan, Rules};
use rayon::prelude::*;

#[path = "../benches/cages/mod.rs"]
mod cages;

/// Items per side of a tile's working arrays (`n + 2^L` are used at level `L`; `n <= 9`,
/// `L <= 4`).
const SIDE: usize = 32;

/// The two phase masks of one 1-D step of degree `n`: replication then `n` averages of
/// neighbours, as `y[2i + p] = sum_t mask[p][t] x[i + t]` (binomial weights `C(n, k) / 2^n`
/// summed over the replicated pairs; `T` taps, see [`taps`], the unused ones zero).
fn phase_masks<const T: usize>(n: usize) -> [[f32; T]; 2] {
    let mut binom = vec![1.0f64];
    for _ in 0..n {
        let mut next = vec![1.0; binom.len() + 1];
        for k in 1..binom.len() {
            next[k] = binom[k - 1] + binom[k];
        }
        binom = next;
    }
    let scale = 0.5f64.powi(n as i32);
    std::array::from_fn(|p| {
        std::array::from_fn(|t| {
            (0..=n)
                .filter(|&k| (p + k) / 2 == t)
                .map(|k| binom[k] * scale)
                .sum::<f64>() as f32
        })
    })
}

/// One tile's working arrays (three channels, `SIDE` rows of `SIDE`), twice.
struct Work {
    a: Box<[[f32; SIDE * SIDE]; 3]>,
    b: Box<[[f32; SIDE * SIDE]; 3]>,
}

/// A 1-D step along rows (`h` rows, row stride `W`) from `x` into `y`: both phases from the
/// same items over the whole row (`W / 2` outputs a phase, fixed trip counts for vectors), then
/// interleaved. Items past a row's valid ones are finite leftovers no output keeps.
#[inline(always)]
fn along_rows<const T: usize, const W: usize>(
    x: &[f32],
    y: &mut [f32],
    h: usize,
    m: &[[f32; T]; 2],
) {
    for r in 0..h {
        // Reads run past the row into the next one (or the array's slack): leftovers.
        let xr = &x[r * W..r * W + W / 2 + T];
        let mut e = [0.0f32; W];
        let mut o = [0.0f32; W];
        for t in 0..T {
            for i in 0..W / 2 {
                let v = xr[i + t];
                e[i] += m[0][t] * v;
                o[i] += m[1][t] * v;
            }
        }
        let yr: &mut [f32; W] = (&mut y[r * W..(r + 1) * W]).try_into().unwrap();
        for i in 0..W / 2 {
            yr[2 * i] = e[i];
            yr[2 * i + 1] = o[i];
        }
    }
}

/// A 1-D step along columns (`h` rows, row stride `W`) from `x` into `y`: `2h - D` rows, each a
/// sum of whole rows (vectors along the row).
#[inline(always)]
fn along_columns<const T: usize, const W: usize>(
    x: &[f32],
    y: &mut [f32],
    h: usize,
    m: &[[f32; T]; 2],
    n: usize,
) {
    for j in 0..2 * h - n {
        let (i, p) = (j / 2, j % 2);
        let mut acc = [0.0f32; W];
        for t in 0..T {
            let xr: &[f32; W] = x[(i + t) * W..(i + t + 1) * W].try_into().unwrap();
            for k in 0..W {
                acc[k] += m[p][t] * xr[k];
            }
        }
        y[j * W..(j + 1) * W].copy_from_slice(&acc);
    }
}

/// The tiles' work: per tile, gather its net, `levels` separable steps (and, for even
/// degrees, the drawing step: one more average each way), then write its `2^L x 2^L` points
/// at `slots` (tile order when `slots` is `None`).
struct Tiling<const T: usize, const W: usize> {
    degree: usize,
    levels: u32,
    masks: [[f32; T]; 2],
    /// Per tile, the `(n + 1)^2` ids of its net.
    nets: Vec<u32>,
    /// Per output point, its place (the scatter case).
    slots: Option<Vec<u32>>,
    /// Index in a tile's last-level arrays of its face's corner 0 (the output block's start).
    offset: usize,
}

impl<const T: usize, const W: usize> Tiling<T, W> {
    fn new(degree: usize, levels: u32, tiles: usize, points: usize, scatter: bool) -> Self {
        let net = (degree + 1) * (degree + 1);
        // Nets of nearby cage points (a tile's net is its face's neighbourhood).
        let nets = (0..tiles * net)
            .map(|k| ((k / net + (k % net) * 37) % points) as u32)
            .collect();
        let per = 1usize << (2 * levels);
        let slots = scatter.then(|| {
            // A fixed permutation of the outputs, in runs of 4 (the present numbering puts a
            // tile's points in a few dozen runs over the level, none of them long).
            let total = tiles * per;
            let runs = total / 4;
            let mut order: Vec<u32> = (0..runs as u32).collect();
            let mut seed = 0x9e37_79b9u64;
            for i in (1..runs).rev() {
                seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
                order.swap(i, (seed >> 33) as usize % (i + 1));
            }
            (0..total)
                .map(|k| 4 * order[k / 4] + (k % 4) as u32)
                .collect()
        });
        Tiling {
            degree,
            levels,
            masks: phase_masks::<T>(degree),
            nets,
            slots,
            offset: 0,
        }
    }

    /// Tiles over given nets (`(n + 1)^2` ids per tile, row after row), each writing the block
    /// that starts at its face's corner 0 (at index `offset` of the last level's arrays).
    fn from_nets(degree: usize, levels: u32, nets: Vec<u32>, offset: usize) -> Self {
        Tiling {
            degree,
            levels,
            masks: phase_masks::<T>(degree),
            nets,
            slots: None,
            offset,
        }
    }

    #[inline(always)]
    fn tile(&self, g: usize, cage: &[[f32; 3]], work: &mut Work, out: &mut [[f32; 3]]) {
        let n = self.degree;
        let side = n + 1;
        let net = &self.nets[g * side * side..(g + 1) * side * side];
        for (k, &id) in net.iter().enumerate() {
            for (a, &x) in work.a.iter_mut().zip(&cage[id as usize]) {
                a[(k / side) * W + k % side] = x;
            }
        }
        let mut h = side;
        for _ in 0..self.levels {
            for c in 0..3 {
                along_rows::<T, W>(&work.a[c], &mut work.b[c], h, &self.masks);
                along_columns::<T, W>(&work.b[c], &mut work.a[c], h, &self.masks, n);
            }
            h = 2 * h - n;
        }
        if n.is_multiple_of(2) {
            // The drawing step: each vertex the mean of its four faces.
            for c in 0..3 {
                let a = &mut work.a[c];
                for j in 0..h - 1 {
                    for i in 0..W - 1 {
                        a[j * W + i] = 0.25
                            * (a[j * W + i]
                                + a[j * W + i + 1]
                                + a[(j + 1) * W + i]
                                + a[(j + 1) * W + i + 1]);
                    }
                }
            }
        }
        let per = 1usize << self.levels;
        for j in 0..per {
            for i in 0..per {
                let at = (j + self.offset) * W + i + self.offset;
                let p = [0, 1, 2].map(|c| work.a[c][at]);
                let k = g * per * per + j * per + i;
                match &self.slots {
                    None => out[k] = p,
                    Some(slots) => out[slots[k] as usize] = p,
                }
            }
        }
    }

    /// The tiles `range`, compiled for AVX2 as the library's kernels are.
    #[target_feature(enable = "avx2")]
    unsafe fn tiles_avx2(
        &self,
        range: std::ops::Range<usize>,
        cage: &[[f32; 3]],
        work: &mut Work,
        out: &mut [[f32; 3]],
    ) {
        for g in range {
            self.tile(g, cage, work, out);
        }
    }

    /// A new output (as [`Plan::evaluate`] returns one), every point written by one tile.
    fn run(&self, cage: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let per = 1usize << (2 * self.levels);
        let tiles = self.nets.len() / ((self.degree + 1) * (self.degree + 1));
        let mut out: Vec<[f32; 3]> = Vec::with_capacity(tiles * per);
        const TASK: usize = 64;
        let out_ptr = SendPtr(out.as_mut_ptr());
        (0..tiles.div_ceil(TASK)).into_par_iter().for_each_init(
            || Work {
                a: Box::new([[0.0; SIDE * SIDE]; 3]),
                b: Box::new([[0.0; SIDE * SIDE]; 3]),
            },
            |work, task| {
                let ptr = &out_ptr;
                // SAFETY: tiles write disjoint points (tile order, or a permutation).
                let out = unsafe { std::slice::from_raw_parts_mut(ptr.0, tiles * per) };
                let range = task * TASK..((task + 1) * TASK).min(tiles);
                // SAFETY: the driver runs where AVX2 is (as the library's kernels check).
                unsafe { self.tiles_avx2(range, cage, work, out) };
            },
        );
        // SAFETY: every point was written (tile order or a permutation of it).
        unsafe { out.set_len(tiles * per) };
        out
    }
}

struct SendPtr(*mut [f32; 3]);
unsafe impl Sync for SendPtr {}
unsafe impl Send for SendPtr {}

/// Taps per phase of a degree's masks (`d / 2 + 2` covers both phases; 4 needs only 3).
fn taps(degree: usize) -> usize {
    match degree {
        4 => 3,
        d => d / 2 + 2,
    }
}

/// Times (or, with `reps`, only runs) the tiles of `degree` (`T` its [`taps`]) at `level`.
fn measure<const T: usize, const W: usize>(
    degree: usize,
    level: u32,
    reps: usize,
    scatter: Option<bool>,
) {
    let (cage, _, _, points) = cages::ico_quad_sphere(8);
    let (corners, _) = points.as_chunks::<3>();
    let tiles = cage.num_faces();
    assert_eq!(taps(degree), T);
    if let Some(scatter) = scatter {
        let tiling = Tiling::<T, W>::new(degree, level, tiles, corners.len(), scatter);
        for _ in 0..reps {
            black_box(tiling.run(corners));
        }
        return;
    }
    let options = Options {
        degree: degree as u32,
        levels: level,
        rules: Rules::Averaging,
        ..Options::default()
    };
    let plan = Plan::new(&cage, &options).unwrap();
    black_box(plan.evaluate(&points, 3).unwrap());
    let tiling = Tiling::<T, W>::new(degree, level, tiles, corners.len(), false);
    let scattered = Tiling::<T, W>::new(degree, level, tiles, corners.len(), true);
    black_box((tiling.run(corners), scattered.run(corners)));
    let best = |work: &mut dyn FnMut()| {
        (0..5)
            .map(|_| {
                let t = Instant::now();
                for _ in 0..reps {
                    work();
                }
                t.elapsed().as_secs_f64() / reps as f64 * 1e6
            })
            .fold(f64::INFINITY, f64::min)
    };
    let p = best(&mut || {
        black_box(plan.evaluate(&points, 3).unwrap());
    });
    let t = best(&mut || {
        black_box(tiling.run(corners));
    });
    let s = best(&mut || {
        black_box(scattered.run(corners));
    });
    println!(
        "{degree:>8} {level:>6} {p:>12.1} {t:>12.1} {s:>12.1} {:>8.2} {:>8.2}",
        p / t,
        p / s
    );
}

/// Checks the tiles against a plan on a torus of `m x m` quads (every vertex regular), degree 3,
/// `levels` levels: every point of the plan's last level must be some tile's, to 1e-5 of the
/// torus's size, and the counts equal. The face's corner 0 is at index 1 of every level's arrays
/// for degree 3 (its first output is the edge point before it). Panics when they differ.
fn verify(m: usize, levels: u32) {
    let id = |i: usize, j: usize| ((i % m) + m * (j % m)) as u32;
    let mut points = Vec::new();
    for j in 0..m {
        for i in 0..m {
            let (u, v) = (
                std::f64::consts::TAU * i as f64 / m as f64,
                std::f64::consts::TAU * j as f64 / m as f64,
            );
            let r = 2.0 + 0.7 * v.cos();
            points.extend([r * u.cos(), r * u.sin(), 0.7 * v.sin()].map(|x| x as f32));
        }
    }
    let faces: Vec<i64> = (0..m * m)
        .flat_map(|f| {
            let (i, j) = (f % m, f / m);
            [id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)].map(i64::from)
        })
        .collect();
    let cage = bidegree::Cage::from_indices(m * m, &vec![4i64; m * m], &faces).unwrap();
    let options = Options {
        degree: 3,
        levels,
        rules: Rules::Averaging,
        ..Options::default()
    };
    let plan = Plan::new(&cage, &options).unwrap();
    let expected = plan.evaluate(&points, 3).unwrap();
    // Each face's net: the 4 x 4 vertices from one before its corner 0 on, rows along j.
    let nets: Vec<u32> = (0..m * m)
        .flat_map(|f| {
            let (i, j) = (f % m + m, f / m + m);
            (0..16).map(move |k| id(i - 1 + k % 4, j - 1 + k / 4))
        })
        .collect();
    let tiling = Tiling::<3, 16>::from_nets(3, levels, nets, 1);
    let (corners, _) = points.as_chunks::<3>();
    let got = tiling.run(corners);
    let (want, _) = expected.as_chunks::<3>();
    assert_eq!(got.len(), want.len(), "one tile point per plan point");
    let cell = |p: &[f32; 3]| p.map(|x| (x * 20.0).floor() as i64);
    let mut grid: std::collections::HashMap<[i64; 3], Vec<[f32; 3]>> = Default::default();
    for p in want {
        grid.entry(cell(p)).or_default().push(*p);
    }
    let mut worst = 0.0f32;
    for p in &got {
        let c = cell(p);
        let nearest = (0..27)
            .filter_map(|k| grid.get(&[c[0] + k % 3 - 1, c[1] + k / 3 % 3 - 1, c[2] + k / 9 - 1]))
            .flatten()
            .map(|q| (0..3).map(|i| (p[i] - q[i]).abs()).fold(0.0, f32::max))
            .fold(f32::INFINITY, f32::min);
        worst = worst.max(nearest);
    }
    assert!(
        worst < 3e-5,
        "a tile point {worst} away from every plan point"
    );
    println!("verified: {} tile points on the plan's, worst {worst:.1e} (torus {m} x {m}, level {levels})", got.len());
}

fn dispatch(degree: usize, level: u32, reps: usize, scatter: Option<bool>) {
    // Rows of 16 or 32 items: the last level's `D + 2^L` and its margins.
    match (taps(degree), degree + (1 << level) <= 16) {
        (3, true) => measure::<3, 16>(degree, level, reps, scatter),
        (3, false) => measure::<3, 32>(degree, level, reps, scatter),
        (6, true) => measure::<6, 16>(degree, level, reps, scatter),
        (6, false) => measure::<6, 32>(degree, level, reps, scatter),
        _ => panic!("degrees 3, 4 and 9"),
    }
}

fn main() {
    assert!(std::arch::is_x86_feature_detected!("avx2"));
    let args: Vec<String> = std::env::args().collect();
    if let Some(case) = args.get(1).filter(|a| a.starts_with("tiles-")) {
        let reps: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(1);
        let rest = case.strip_prefix("tiles-").unwrap_or_default();
        let (scatter, rest) = match rest.strip_prefix("scatter-") {
            Some(r) => (true, r),
            None => (false, rest),
        };
        let (d, l) = rest.split_once('-').expect("tiles-[scatter-]D-L");
        dispatch(d.parse().unwrap(), l.parse().unwrap(), reps, Some(scatter));
        return;
    }
    if args.get(1).is_some_and(|a| a == "verify") {
        verify(16, 3);
        return;
    }
    let level: u32 = args.get(1).and_then(|l| l.parse().ok()).unwrap_or(3);
    let reps: usize = args.get(2).and_then(|r| r.parse().ok()).unwrap_or(50);
    println!(
        "{:>8} {:>6} {:>12} {:>12} {:>12} {:>8} {:>8}",
        "degree", "level", "plan us", "tiles us", "scatter us", "p/t", "p/s"
    );
    for degree in [3usize, 4, 9] {
        dispatch(degree, level, reps, None);
    }
}
