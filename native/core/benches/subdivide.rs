//! `cargo bench -p bidegree`: output faces per second for degrees 1..9 at about 4M output faces,
//! fresh (plan + evaluate) and through a cached plan, next to a plain memory copy of the same
//! output size measured in the same run. The ratio to the copy is the figure that matters.
//! A second table times limit positions and normals (`Plan::limit_surface`) at about 250k
//! output faces against an evaluation through the same plan (`BIDEGREE_BENCH_LIMIT=0` skips it).

use std::hint::black_box;
use std::time::{Duration, Instant};

use bidegree::{subdivide, Cage, Options, Plan};

mod allocator;

/// A cube whose faces are n x n grids, projected to a sphere: 8 vertices of valence 3.
fn quad_sphere(n: usize) -> (Cage, Vec<f32>) {
    let mut index = std::collections::HashMap::new();
    let mut points: Vec<f32> = Vec::new();
    let mut faces: Vec<i64> = Vec::new();
    let mut id = |p: [i64; 3], points: &mut Vec<f32>| -> i64 {
        *index.entry(p).or_insert_with(|| {
            let v = [p[0] as f32, p[1] as f32, p[2] as f32];
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            points.extend(v.iter().map(|x| x / len));
            (points.len() / 3 - 1) as i64
        })
    };
    let h = n as i64;
    for axis in 0..3 {
        for sign in [-1i64, 1] {
            for a in 0..n as i64 {
                for b in 0..n as i64 {
                    let at = |a: i64, b: i64| {
                        let mut p = [0i64; 3];
                        p[axis] = sign * h;
                        p[(axis + 1) % 3] = 2 * a - h;
                        p[(axis + 2) % 3] = 2 * b - h;
                        p
                    };
                    let mut quad = [at(a, b), at(a + 1, b), at(a + 1, b + 1), at(a, b + 1)];
                    if sign < 0 {
                        quad.reverse();
                    }
                    for p in quad {
                        faces.push(id(p, &mut points));
                    }
                }
            }
        }
    }
    let sizes = vec![4i64; faces.len() / 4];
    (
        Cage::from_indices(points.len() / 3, &sizes, &faces).unwrap(),
        points,
    )
}

fn best_of(repeat: usize, mut f: impl FnMut()) -> Duration {
    (0..repeat)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed()
        })
        .min()
        .unwrap()
}

fn main() {
    let target_faces: f64 = std::env::var("BIDEGREE_BENCH_FACES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(4e6);
    let (cage, points) = quad_sphere(13);
    println!(
        "cage: {} vertices, {} quads (8 of valence 3); {} threads",
        cage.num_vertices(),
        cage.num_faces(),
        rayon::current_num_threads()
    );
    println!(
        "{:>6} {:>6} {:>10} {:>12} {:>12} {:>9} {:>9} {:>8} {:>11}",
        "degree",
        "levels",
        "faces",
        "fresh f/s",
        "cached f/s",
        "plan ms",
        "eval ms",
        "copy ms",
        "cached/copy"
    );
    // BIDEGREE_BENCH_DEGREES=3 or 1,3,5 restricts the run (for profiling).
    let degrees: Vec<u32> = std::env::var("BIDEGREE_BENCH_DEGREES")
        .ok()
        .map(|s| s.split(',').filter_map(|d| d.trim().parse().ok()).collect())
        .unwrap_or_else(|| (1..=9).collect());
    for degree in degrees {
        let levels = ((target_faces / (4.0 * cage.num_faces() as f64))
            .log(4.0)
            .round() as u32
            + 1)
        .max(1);
        let options = Options {
            degree,
            levels,
            ..Options::default()
        };
        let plan = Plan::new(&cage, &options).unwrap();
        let faces = plan.num_output_faces() as f64;
        let fresh = best_of(3, || {
            black_box(subdivide(&cage, &points, 3, &options).unwrap());
        });
        // BIDEGREE_BENCH_LOOP=n: only n cached evaluations (for profiling them).
        if let Some(n) = std::env::var("BIDEGREE_BENCH_LOOP")
            .ok()
            .and_then(|s| s.parse::<usize>().ok())
        {
            let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
            for _ in 0..n {
                black_box(plan.evaluate(&moved, 3).unwrap());
            }
            continue;
        }
        let build = best_of(3, || {
            black_box(Plan::new(&cage, &options).unwrap());
        });
        let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
        let cached = best_of(5, || {
            black_box(plan.evaluate(&moved, 3).unwrap());
        });
        let src = vec![1.0f32; 3 * plan.num_output_vertices()];
        let mut dst = vec![0.0f32; src.len()];
        let copy = best_of(5, || {
            dst.copy_from_slice(black_box(&src));
            black_box(&dst);
        });
        println!(
            "{:>6} {:>6} {:>10} {:>12.3e} {:>12.3e} {:>9.1} {:>9.1} {:>8.2} {:>11.1}",
            degree,
            levels,
            faces,
            faces / fresh.as_secs_f64(),
            faces / cached.as_secs_f64(),
            build.as_secs_f64() * 1e3,
            cached.as_secs_f64() * 1e3,
            copy.as_secs_f64() * 1e3,
            cached.as_secs_f64() / copy.as_secs_f64()
        );
    }
    if std::env::var("BIDEGREE_BENCH_LIMIT").as_deref() != Ok("0") {
        limit_table(&cage, &points);
    }
}

/// Limit positions and normals next to a cached evaluation of the same plan.
fn limit_table(cage: &Cage, points: &[f32]) {
    println!(
        "\nlimit surface (positions and normals) vs evaluate, same plan\n{:>6} {:>6} {:>10} {:>6} {:>10} {:>10} {:>9} {:>6}",
        "degree", "levels", "faces", "extra", "first ms", "cached ms", "eval ms", "ratio"
    );
    let levels = ((2.5e5 / (4.0 * cage.num_faces() as f64)).log(4.0).round() as u32 + 1).max(1);
    for degree in [2u32, 3, 4, 5, 9] {
        let options = Options {
            degree,
            levels,
            ..Options::default()
        };
        let plan = Plan::new(cage, &options).unwrap();
        let t = Instant::now();
        black_box(plan.limit_surface(points).unwrap());
        let first = t.elapsed();
        let extra = plan.limit_extra_levels().unwrap();
        let cached = best_of(5, || {
            black_box(plan.limit_surface(points).unwrap());
        });
        let eval = best_of(5, || {
            black_box(plan.evaluate(points, 3).unwrap());
        });
        println!(
            "{:>6} {:>6} {:>10} {:>6} {:>10.1} {:>10.1} {:>9.1} {:>6.1}",
            degree,
            levels,
            plan.num_output_faces(),
            extra,
            first.as_secs_f64() * 1e3,
            cached.as_secs_f64() * 1e3,
            eval.as_secs_f64() * 1e3,
            cached.as_secs_f64() / eval.as_secs_f64()
        );
    }
}
