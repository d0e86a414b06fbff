//! A deterministic driver for instruction counts under callgrind (the machine is shared, so
//! wall-clock times are noise; instruction counts are not). `callgrind CASE REPS` builds the
//! input, then does the case's work `REPS` times; the cost of one is the difference of the
//! counts of `REPS = 2` and `REPS = 1` (the work runs on rayon's threads, so callgrind's
//! per-thread `--toggle-collect` cannot isolate it):
//!
//! ```sh
//! cargo build -p bidegree --release --example callgrind
//! ir() { RAYON_NUM_THREADS=1 valgrind --tool=callgrind --callgrind-out-file=/dev/null \
//!          target/release/examples/callgrind "$@" 2>&1 | awk '/Collected/ {print $4}'; }
//! for case in fresh-averaging-3 cached-averaging-3 fresh-classic-3 cached-classic-3 \
//!             fresh-averaging-4 cached-averaging-4 fresh-averaging-9 cached-averaging-9 \
//!             limit-surface-4 adaptive-4 adaptive-flat-4-5 adaptive-uniform-4-5 limit-ico-4 limit-first-ico-4 limit-first-fan-400-9 \
//!             limit-first-ngon-1000-9 limit-semisharp-4 limit-sharp-4 limit-positions-ico-4 \
//!             uvs-classic-3 uvs-averaging-4 uvs-first-classic-3 uvs-first-averaging-4 \
//!             uvs-shared-classic-3 uvs-shared-averaging-4 \
//!             fresh-fins-averaging-3 fresh-flipped-averaging-3 fresh-loose-fins-averaging-3 \
//!             fresh-fins-classic-3 fresh-flipped-classic-3; do
//!   echo "$case $(( $(ir $case 2) - $(ir $case 1) ))"
//! done
//! ```
//!
//! Cage: the 3,840-quad ico-quad sphere of the OpenSubdiv benchmark, f32 points, level 3
//! (`CALLGRIND_LEVELS=L` sets another level for the sphere's cases: Blender's viewport and
//! render defaults are 1 and 2).
//! A scheme is `classic-3` or `averaging-D` for any degree D (`cached-averaging-7`, ...).
//! "fresh" is `Plan::new` and one `evaluate`; "cached" one `evaluate` through a plan that has
//! already evaluated once (its kept buffers warm); the limit case is `limit_surface` on a new
//! plan (stencils built on the first call) and the adaptive case one `subdivide_adaptive` at
//! tolerance 1e-4, max level 3; "adaptive-flat-D-L" and "adaptive-uniform-D-L" are the two sides
//! of a row of the adaptive bench (`benches/adaptive.rs`: its cage, degree D, max level L), the
//! adaptive one at the uniform surface's error (measured outside the counted work). "uvs" is a cached `evaluate_face_varying` of UVs with a seam
//! around every base patch (mode `boundaries`), to compare with "cached" of the same scheme;
//! "uvs-first" is a new plan's first `evaluate_face_varying` (the face-varying mesh built), to
//! compare with "fresh"; "uvs-shared" the cached UVs in the indexed form
//! (`evaluate_face_varying_shared`); "limit-positions-ico-D" a cached `limit_positions` (no
//! normals) on the sphere.
//!
//! Generic code is instantiated in this binary, so LLVM's inlining of the library's steps
//! depends on every case here: an A/B of a change compares two builds of the same file.

use std::hint::black_box;

use bidegree::{subdivide_adaptive, AdaptiveOptions, Cage, FaceVaryingMode, Options, Plan, Rules};

#[path = "../benches/allocator/mod.rs"]
mod allocator;
#[path = "../benches/cages/mod.rs"]
mod cages;
#[path = "../benches/cages/flat.rs"]
mod flat;

fn main() {
    let usage = || -> ! {
        eprintln!("usage: callgrind CASE REPS (see the module documentation)");
        std::process::exit(2);
    };
    let args: Vec<String> = std::env::args().collect();
    let (Some(case), Some(reps)) = (args.get(1), args.get(2).and_then(|r| r.parse().ok())) else {
        usage()
    };
    let case = case.as_str();
    let measured = |work: &dyn Fn()| {
        for _ in 0..reps {
            work();
        }
    };
    let (cage, _, cage_indices, points) = cages::ico_quad_sphere(8);
    let sphere_levels: u32 = match std::env::var("CALLGRIND_LEVELS") {
        Ok(l) => l.parse().unwrap_or_else(|_| usage()),
        Err(_) => 3,
    };
    let options = |degree: u32, rules: Rules| Options {
        degree,
        levels: sphere_levels,
        rules,
        ..Options::default()
    };
    let scheme = |name: &str| -> Option<Options> {
        Some(match name {
            "classic-3" => options(3, Rules::Classic),
            _ => options(
                name.strip_prefix("averaging-")?.parse().ok()?,
                Rules::Averaging,
            ),
        })
    };
    // fresh-fins-SCHEME, fresh-flipped-SCHEME: the same sphere made non-manifold (issue 13), for
    // the cost of the non-manifold tables against the manifold "fresh" case of the same build:
    // "fins" adds a quad (two new points, pushed out) on the first edge of every 40th face (96
    // edges of 3 faces, 2.5 % more faces); "flipped" reverses every 40th face (the same faces,
    // 384 edges whose two faces run the same way); "loose-fins" the same fins on their own
    // copies of the edge's points (the same faces and boundary curves, nothing non-manifold).
    let dirty = |how: &str| -> (Cage, Vec<f32>) {
        let (mut indices, mut points) = (cage_indices.clone(), points.clone());
        let quads = indices.len() / 4;
        for q in (0..quads).step_by(40) {
            let [a, b] = [indices[4 * q], indices[4 * q + 1]];
            if how == "flipped" {
                indices[4 * q..4 * q + 4].reverse();
                continue;
            }
            let first = (points.len() / 3) as u32;
            let [a, b] = if how == "loose-fins" {
                // The same quads on their own copies of the edge: no non-manifold edge.
                let copy = (points.len() / 3) as u32;
                for v in [a, b] {
                    let p: Vec<f32> = points[3 * v as usize..3 * v as usize + 3].to_vec();
                    points.extend(p);
                }
                [copy, copy + 1]
            } else {
                [a, b]
            };
            let first = first + if how == "loose-fins" { 2 } else { 0 };
            for v in [b, a] {
                let p: Vec<f32> = points[3 * v as usize..3 * v as usize + 3].to_vec();
                points.extend(p.iter().map(|x| 1.2 * x));
            }
            indices.extend([a, b, first, first + 1]);
        }
        let sizes = vec![4i64; indices.len() / 4];
        let faces: Vec<i64> = indices.iter().map(|&i| i as i64).collect();
        (
            Cage::from_indices(points.len() / 3, &sizes, &faces).unwrap(),
            points,
        )
    };
    let dirty_case = ["fins", "loose-fins", "flipped"]
        .into_iter()
        .find_map(|how| {
            let o = case
                .strip_prefix("fresh-")?
                .strip_prefix(how)?
                .strip_prefix('-')?;
            Some((how, scheme(o)?))
        });
    if let Some((how, o)) = dirty_case {
        let (cage, points) = dirty(how);
        measured(&|| {
            let plan = Plan::new(&cage, &o).unwrap();
            black_box(plan.evaluate(&points, 3).unwrap());
        });
    } else if let Some(o) = case.strip_prefix("fresh-").and_then(scheme) {
        measured(&|| {
            let plan = Plan::new(&cage, &o).unwrap();
            black_box(plan.evaluate(&points, 3).unwrap());
        });
    } else if let Some(o) = case.strip_prefix("cached-").and_then(scheme) {
        let plan = Plan::new(&cage, &o).unwrap();
        black_box(plan.evaluate(&points, 3).unwrap());
        measured(&|| {
            black_box(plan.evaluate(&points, 3).unwrap());
        });
    } else if case == "limit-surface-4" {
        measured(&|| {
            let plan = Plan::new(&cage, &options(4, Rules::Averaging)).unwrap();
            black_box(plan.limit_surface(&points).unwrap());
        });
    } else if let Some(degree) = case
        .strip_prefix("limit-positions-ico-")
        .and_then(|d| d.parse::<u32>().ok())
    {
        // A cached limit_positions on the ico sphere (positions alone: limit-ico-D less the
        // normals).
        let o = Options {
            degree,
            levels: sphere_levels,
            ..Options::default()
        };
        let plan = Plan::new(&cage, &o).unwrap();
        black_box(plan.limit_positions(&points, 3).unwrap());
        measured(&|| {
            black_box(plan.limit_positions(&points, 3).unwrap());
        });
    } else if let Some((shape, degree)) = case
        .strip_prefix("limit-")
        .and_then(|rest| rest.rsplit_once('-'))
        .and_then(|(shape, d)| Some((shape, d.parse::<u32>().ok()?)))
    {
        // limit-[first-]SHAPE-D, SHAPE one of fan-400, ngon-1000, semisharp, sharp, ico: the
        // limit cases of issue 16 (degree D, level 2 except the ico sphere's level 3); "first"
        // builds the plan and its stencils (the masks stay cached per process), without it a
        // cached call is timed.
        let (first, shape) = match shape.strip_prefix("first-") {
            Some(shape) => (true, shape),
            None => (false, shape),
        };
        let (cage, points) = match shape {
            "fan-400" => cages::triangle_fan(400),
            "ngon-1000" => cages::polygon(1000),
            "semisharp" => cages::creased_grid(12, 7.5),
            "sharp" => cages::creased_grid(12, 10.0),
            "ico" => (cage.clone(), points.clone()),
            _ => usage(),
        };
        let levels = if shape == "ico" { sphere_levels } else { 2 };
        let o = Options {
            degree,
            levels,
            ..Options::default()
        };
        if first {
            measured(&|| {
                let plan = Plan::new(&cage, &o).unwrap();
                black_box(plan.limit_surface(&points).unwrap());
            });
        } else {
            let plan = Plan::new(&cage, &o).unwrap();
            black_box(plan.limit_surface(&points).unwrap());
            measured(&|| {
                black_box(plan.limit_surface(&points).unwrap());
            });
        }
    } else if let Some(o) = case.strip_prefix("uvs-first-").and_then(scheme) {
        // The first smooth UVs of a new plan: the plan, the face-varying topology (weld, M^fv,
        // its refinement) and one evaluation; minus "fresh" of the same scheme, M^fv's cost.
        let uvs = cages::ico_patch_uvs(8, &cage_indices, &points);
        measured(&|| {
            let plan = Plan::new(&cage, &o).unwrap();
            let mode = FaceVaryingMode::Boundaries;
            black_box(plan.evaluate_face_varying(&uvs, 2, mode, false).unwrap());
        });
    } else if let Some(o) = case.strip_prefix("uvs-shared-").and_then(scheme) {
        // As "uvs", in the indexed form: one value per face-varying vertex, the kept indices.
        let uvs = cages::ico_patch_uvs(8, &cage_indices, &points);
        let plan = Plan::new(&cage, &o).unwrap();
        let mode = FaceVaryingMode::Boundaries;
        let shared = |plan: &Plan| plan.evaluate_face_varying_shared(&uvs, 2, None, mode, false);
        black_box(shared(&plan).unwrap());
        measured(&|| {
            black_box(shared(&plan).unwrap());
        });
    } else if let Some(o) = case.strip_prefix("uvs-").and_then(scheme) {
        // Smooth UVs (mode `boundaries`) of the face-varying bench's layout: every base patch of
        // the sphere its own island; cached (the face-varying topology built before).
        let n = 8;
        let uvs = cages::ico_patch_uvs(n, &cage_indices, &points);
        let plan = Plan::new(&cage, &o).unwrap();
        let mode = FaceVaryingMode::Boundaries;
        black_box(plan.evaluate_face_varying(&uvs, 2, mode, false).unwrap());
        measured(&|| {
            black_box(plan.evaluate_face_varying(&uvs, 2, mode, false).unwrap());
        });
    } else if case == "adaptive-4" {
        let adaptive = AdaptiveOptions {
            degree: 4,
            max_level: 3,
            tolerance: 1e-4,
            ..AdaptiveOptions::default()
        };
        measured(&|| {
            black_box(subdivide_adaptive(&cage, &points, &adaptive).unwrap());
        });
    } else if let Some((uniform, degree, level)) = case
        .strip_prefix("adaptive-flat-")
        .map(|rest| (false, rest))
        .or_else(|| {
            case.strip_prefix("adaptive-uniform-")
                .map(|rest| (true, rest))
        })
        .and_then(|(uniform, rest)| {
            let (d, l) = rest.split_once('-')?;
            Some((uniform, d.parse::<u32>().ok()?, l.parse::<u32>().ok()?))
        })
    {
        // adaptive-flat-D-L and adaptive-uniform-D-L: the two sides of a row of the adaptive
        // bench (its cage, degree D, max level L), adaptive at the tolerance of the uniform
        // surface's own error (measured outside the counted work) and the uniform plan's
        // `Plan::new` and `evaluate`.
        let (cage, points) = flat::flat_with_detail(16);
        let adaptive = |tolerance: f64, measure_leaves: bool| AdaptiveOptions {
            degree,
            max_level: level,
            tolerance,
            measure_leaves,
            ..AdaptiveOptions::default()
        };
        if uniform {
            let o = Options {
                degree,
                levels: level,
                ..Options::default()
            };
            measured(&|| {
                let plan = Plan::new(&cage, &o).unwrap();
                black_box(plan.evaluate(&points, 3).unwrap());
            });
        } else {
            // For a profile of the adaptive work alone, ADAPTIVE_TOLERANCE_BITS (the tolerance's
            // f64 bits, printed by a run without it) skips the measurement of the uniform error.
            let tolerance = match std::env::var("ADAPTIVE_TOLERANCE_BITS") {
                Ok(bits) => f64::from_bits(bits.parse().unwrap_or_else(|_| usage())),
                Err(_) => subdivide_adaptive(&cage, &points, &adaptive(0.0, true))
                    .unwrap()
                    .max_error
                    .unwrap(),
            };
            eprintln!("tolerance bits: {}", tolerance.to_bits());
            measured(&|| {
                black_box(subdivide_adaptive(&cage, &points, &adaptive(tolerance, false)).unwrap());
            });
        }
    } else {
        usage()
    }
}
