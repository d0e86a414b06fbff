//! `cargo bench -p bidegree --bench face_varying`: smooth face-varying values (UVs) against
//! positions through the same plan, in the same run (issue 14's target: smooth UVs cost at most
//! 2x positions, cached). The cage is `scripts/bench_opensubdiv.sh`'s ico-quad sphere (253,500
//! quads; `BIDEGREE_BENCH_N=8` for the 3,840-quad one) with a seamed UV layout: each of its 60
//! base patches is its own UV island (the patch's x, y shifted per patch), so every patch border
//! is a seam. Rows: classic degree 3 and averaging degree 4 at levels 2 and 3: positions
//! (3 channels, `Plan::evaluate`), then UVs (2 channels, `Plan::evaluate_face_varying` in
//! `boundaries` and `none`) first (the face-varying mesh is refined) and cached, and the ratio
//! cached UVs / cached positions (the median of the ratios of pairs timed in turn); then the
//! same for UVs in the indexed form (`Plan::evaluate_face_varying_shared`: one value per
//! face-varying vertex and the kept index per corner, OpenSubdiv's and USD's form). f32,
//! medians of 3 to 21 repetitions after a warm-up
//! (`BIDEGREE_BENCH_SECONDS`, default 1; `BIDEGREE_BENCH_LEVELS`, default `2,3`); the load
//! average is printed with the rows.

use std::hint::black_box;
use std::time::Instant;

use bidegree::{FaceVaryingMode, Options, Plan, Rules};

mod allocator;
mod cages;
use cages::{ico_patch_uvs, ico_quad_sphere};

fn elapsed_ms<R>(f: &mut impl FnMut() -> R) -> f64 {
    let t = Instant::now();
    let r = f();
    let ms = t.elapsed().as_secs_f64() * 1e3;
    drop(black_box(r));
    ms
}

fn median(mut times: Vec<f64>) -> f64 {
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// Medians of `a`'s and `b`'s times and of the ratios b / a, the two timed in turn (a, b, a,
/// b, ...) so that each ratio compares runs a few milliseconds apart, whatever the machine's
/// other load does meanwhile.
fn paired_ms<R, S>(
    seconds: f64,
    mut a: impl FnMut() -> R,
    mut b: impl FnMut() -> S,
) -> (f64, f64, f64) {
    let warmup = elapsed_ms(&mut a) + elapsed_ms(&mut b);
    let reps = ((seconds * 1e3 / warmup.max(1e-3)) as usize).clamp(3, 21);
    let (mut ta, mut tb, mut ratios) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..reps {
        let (x, y) = (elapsed_ms(&mut a), elapsed_ms(&mut b));
        ta.push(x);
        tb.push(y);
        ratios.push(y / x);
    }
    (median(ta), median(tb), median(ratios))
}

fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|_| "unknown".into())
}

fn main() {
    let env = |name: &str, default: f64| {
        std::env::var(name)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(default)
    };
    let n = env("BIDEGREE_BENCH_N", 65.0) as usize;
    let seconds = env("BIDEGREE_BENCH_SECONDS", 1.0);
    let levels_list: Vec<u32> = std::env::var("BIDEGREE_BENCH_LEVELS")
        .unwrap_or_else(|_| "2,3".into())
        .split(',')
        .filter_map(|l| l.trim().parse().ok())
        .collect();
    let (cage, _, indices, points) = ico_quad_sphere(n);
    let uvs = ico_patch_uvs(n, &indices, &points);
    println!(
        "face-varying bench: {} quads, 60 UV islands; load average {}",
        cage.num_faces(),
        load_average()
    );
    println!(
        "{:<12} {:>5} {:>13} {:>10} {:>13} {:>12} {:>7} {:>15} {:>7}",
        "scheme",
        "level",
        "positions ms",
        "mode",
        "UVs first ms",
        "UVs ms",
        "ratio",
        "UVs indexed ms",
        "ratio"
    );
    for (name, degree, rules) in [
        ("classic 3", 3, Rules::Classic),
        ("averaging 4", 4, Rules::Averaging),
    ] {
        for levels in levels_list.iter().copied() {
            let options = Options {
                degree,
                levels,
                rules,
                ..Options::default()
            };
            let plan = Plan::new(&cage, &options).expect("a plan of the bench cage");
            for mode in [FaceVaryingMode::Boundaries, FaceVaryingMode::None] {
                let t = Instant::now();
                black_box(plan.evaluate_face_varying(&uvs, 2, mode, false).unwrap());
                let first = t.elapsed().as_secs_f64() * 1e3;
                let (positions, cached, ratio) = paired_ms(
                    seconds,
                    || plan.evaluate(&points, 3).unwrap(),
                    || plan.evaluate_face_varying(&uvs, 2, mode, false).unwrap(),
                );
                let (_, shared, shared_ratio) = paired_ms(
                    seconds,
                    || plan.evaluate(&points, 3).unwrap(),
                    || {
                        plan.evaluate_face_varying_shared(&uvs, 2, None, mode, false)
                            .unwrap()
                    },
                );
                println!(
                    "{name:<12} {levels:>5} {positions:>13.1} {:>10} {first:>13.1} {cached:>12.1} \
                     {ratio:>7.2} {shared:>15.1} {shared_ratio:>7.2}",
                    format!("{mode:?}").to_lowercase(),
                );
            }
        }
    }
    println!("load average after: {}", load_average());
}
