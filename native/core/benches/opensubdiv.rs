//! `cargo bench -p bidegree --bench opensubdiv` (normally through `scripts/bench_opensubdiv.sh`,
//! which builds the OpenSubdiv driver and sets `BIDEGREE_OSD_DRIVER`): output faces per second
//! of bidegree next to OpenSubdiv's own uniform refinement of the same cage, in the same run.
//!
//! Cages: an icosahedron whose 20 triangles are each split into 3 quads (60 quads; 12 vertices
//! of valence 5, 20 of valence 3), every quad an n x n grid, projected to the unit sphere: closed,
//! all quads, 32 extraordinary vertices. n = 8 gives 3,840 quads, n = 65 gives 253,500.
//!
//! Rows: OpenSubdiv catmark (edge-only boundaries, no creases; `bench/opensubdiv/driver.cpp`),
//! then bidegree classic Catmull-Clark (degree 3, `Rules::Classic`) and averaging degrees 3, 4
//! and 9, at levels 2, 3 and 4. "fresh" is everything from the cage (OpenSubdiv: refiner
//! factory + RefineUniform + PrimvarRefiner::Interpolate; bidegree: Plan::new + evaluate),
//! "cached" only the points through existing topology (Interpolate; Plan::evaluate). Times are
//! medians of 3 to 21 repetitions after a warm-up. The ratios are bidegree's faces/s over
//! OpenSubdiv's for the same cage and level (> 1: bidegree faster). Each bidegree row is
//! measured twice: on rayon's default pool, then (suffix `1t`) on a pool of one thread, against
//! OpenSubdiv's one thread. The last column, `/copy`, is the cached time over that of copying
//! the output into a new vector (1: memory speed).
//!
//! Environment: `BIDEGREE_OSD_DRIVER` (path of the driver; without it only bidegree's numbers
//! are printed), `BIDEGREE_BENCH_SECONDS` (target time per measurement, default 1),
//! `BIDEGREE_BENCH_MAX_GIB` (skip a row whose memory estimate exceeds this, default 13: the
//! crate's `estimate`, which assumes f64 evaluation buffers, says 12.4 GiB for the 250k cage at
//! level 4 where the measured peak RSS of this bench was 7.9 GiB; OpenSubdiv's was 9.9 GiB),
//! `BIDEGREE_BENCH_CAGES` (e.g. `4k` or `4k,250k`), `BIDEGREE_BENCH_LEVELS` (e.g. `2,3`),
//! `BIDEGREE_BENCH_SCHEMES` (e.g. `classic 3,averaging 4`), `BIDEGREE_BENCH_LIMIT` (`0` skips
//! the limit rows).
//!
//! Limit rows (issue 16, [`limit_rows`]): on the 4k cage, averaging degrees 2..9 at the
//! benchmark's levels (4 skipped: minutes per row), `Plan::limit_surface` (positions and
//! normals) against `Plan::evaluate` of the same plan, both cached ("limit/eval", target
//! <= 2), and the first call (`Plan::new` + `limit_surface`, the limit masks already cached in
//! the process) against a fresh `Plan::new` + `evaluate` ("first/fresh", target <= 3).
//! In instructions (`examples/callgrind.rs`, one thread, level 3; 2026-12-03, lim16b) the first
//! call costs 5.0x (degree 3), 6.0x (4) and 14x (9) a fresh evaluation (10.5x, 13.1x and 27x
//! before the chunked stencil walk), the cached one 4.3x, 2.7x and 6.9x a cached evaluation (5.5x,
//! 3.2x and 7.4x before); see the README's limit paragraph.
//!
//! Hard limit rows ([`hard_limit_rows`]): the other limit targets in wall time, the
//! cages of the callgrind driver's `limit-*` cases at level 2: a 12 x 12 grid with one crease
//! of sharpness 7.5 against the same crease infinitely sharp ("semi/sharp", target <= 1, cached
//! and first call), and the first call of a valence-400 triangle fan and of a single 1000-gon at
//! degree 9 (target under 1 s).

use std::collections::HashMap;
use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use bidegree::{estimate, Options, Plan, Rules};

mod cages;
use cages::{creased_grid, ico_quad_sphere, polygon, triangle_fan};

/// Writes the cage in the driver's format (see `bench/opensubdiv/driver.cpp`).
fn write_cage(path: &Path, sizes: &[u32], indices: &[u32], points: &[f32]) {
    let mut out = Vec::with_capacity(8 + 4 * (sizes.len() + indices.len() + points.len()));
    out.extend(((points.len() / 3) as u32).to_le_bytes());
    out.extend((sizes.len() as u32).to_le_bytes());
    for &x in sizes.iter().chain(indices) {
        out.extend(x.to_le_bytes());
    }
    for &x in points {
        out.extend(x.to_le_bytes());
    }
    std::fs::write(path, out).expect("write the cage file for the OpenSubdiv driver");
}

/// OpenSubdiv's median times for one level (milliseconds).
struct OsdTimes {
    faces: u64,
    fresh_ms: f64,
    cached_ms: f64,
    topology_ms: f64,
    peak_rss_mib: f64,
}

/// Runs the driver on `cage` for `levels`; parses its `osd key=value ...` lines.
fn run_driver(driver: &Path, cage: &Path, levels: &[u32], seconds: f64) -> HashMap<u32, OsdTimes> {
    let list: Vec<String> = levels.iter().map(|l| l.to_string()).collect();
    let output = Command::new(driver)
        .arg(cage)
        .arg(list.join(","))
        .arg(seconds.to_string())
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", driver.display()));
    if !output.status.success() {
        panic!(
            "{} failed ({}): {}",
            driver.display(),
            output.status,
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let mut times = HashMap::new();
    for line in String::from_utf8_lossy(&output.stdout).lines() {
        let Some(rest) = line.strip_prefix("osd ") else {
            continue;
        };
        let fields: HashMap<&str, f64> = rest
            .split_whitespace()
            .filter_map(|kv| kv.split_once('='))
            .filter_map(|(k, v)| Some((k, v.parse().ok()?)))
            .collect();
        let get = |k: &str| fields.get(k).copied().expect("driver line field");
        times.insert(
            get("level") as u32,
            OsdTimes {
                faces: get("faces") as u64,
                fresh_ms: get("fresh_ms"),
                cached_ms: get("cached_ms"),
                topology_ms: get("topology_ms"),
                peak_rss_mib: get("peak_rss_mib"),
            },
        );
    }
    times
}

/// Median wall time (ms) of `f` over 3 to 21 repetitions after one warm-up; the value `f`
/// returns is dropped outside the timed region (as the driver does).
fn median_ms<R>(seconds: f64, mut f: impl FnMut() -> R) -> f64 {
    let once = |f: &mut dyn FnMut() -> R| {
        let t = Instant::now();
        let r = f();
        let ms = t.elapsed().as_secs_f64() * 1e3;
        drop(black_box(r));
        ms
    };
    let warmup = once(&mut f);
    let reps = ((seconds * 1e3 / warmup.max(1e-3)) as usize).clamp(3, 21);
    // A warm-up longer than the target counts as the first sample (keeps the big rows short).
    let mut times: Vec<f64> = if warmup > seconds * 1e3 {
        std::iter::once(warmup)
            .chain((1..reps).map(|_| once(&mut f)))
            .collect()
    } else {
        (0..reps).map(|_| once(&mut f)).collect()
    };
    times.sort_by(f64::total_cmp);
    let n = times.len();
    if n % 2 == 1 {
        times[n / 2]
    } else {
        0.5 * (times[n / 2 - 1] + times[n / 2])
    }
}

/// The 1, 5 and 15 minute load averages (Linux), or "unknown".
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

const GIB: f64 = (1u64 << 30) as f64;

fn env_list<T: std::str::FromStr>(name: &str) -> Option<Vec<T>> {
    std::env::var(name)
        .ok()
        .map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect())
}

fn main() {
    let seconds: f64 = std::env::var("BIDEGREE_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    let max_gib: f64 = std::env::var("BIDEGREE_BENCH_MAX_GIB")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(13.0);
    let levels: Vec<u32> = env_list("BIDEGREE_BENCH_LEVELS").unwrap_or_else(|| vec![2, 3, 4]);
    let cages: Vec<String> =
        env_list("BIDEGREE_BENCH_CAGES").unwrap_or_else(|| vec!["4k".into(), "250k".into()]);
    let schemes_wanted: Option<Vec<String>> = env_list("BIDEGREE_BENCH_SCHEMES");
    let driver = std::env::var_os("BIDEGREE_OSD_DRIVER").map(PathBuf::from);
    match &driver {
        Some(d) if d.is_file() => println!("OpenSubdiv driver: {}", d.display()),
        Some(d) => {
            println!(
                "BIDEGREE_OSD_DRIVER={} is not a file: bidegree numbers only \
                 (scripts/bench_opensubdiv.sh builds the driver)",
                d.display()
            );
        }
        None => println!(
            "BIDEGREE_OSD_DRIVER is not set: bidegree numbers only \
             (scripts/bench_opensubdiv.sh builds the OpenSubdiv driver and sets it)"
        ),
    }
    let driver = driver.filter(|d| d.is_file());
    let dir = PathBuf::from(option_env!("CARGO_TARGET_TMPDIR").unwrap_or("/tmp"));
    println!(
        "{} rayon threads (OpenSubdiv's Far refinement is single-threaded); load average {}; \
         times are medians; ratio = bidegree faces/s / OpenSubdiv faces/s",
        rayon::current_num_threads(),
        load_average()
    );
    let header = format!(
        "{:>5} {:>5} {:<14} {:>10} {:>11} {:>11} {:>8} {:>8} {:>8}",
        "cage",
        "level",
        "scheme",
        "faces",
        "fresh f/s",
        "cached f/s",
        "fresh x",
        "cached x",
        "/copy"
    );
    let default_pool = rayon::ThreadPoolBuilder::new()
        .build()
        .expect("a thread pool");
    let one_thread = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("a thread pool of one thread");
    for name in &cages {
        let n = match name.as_str() {
            "4k" => 8,
            "250k" => 65,
            other => {
                println!("unknown cage {other:?} (4k or 250k)");
                continue;
            }
        };
        let (cage, sizes, indices, points) = ico_quad_sphere(n);
        println!(
            "\ncage {name}: {} vertices, {} quads (ico-quad sphere, n = {n}: 12 valence-5 and 20 valence-3 vertices)",
            cage.num_vertices(),
            cage.num_faces()
        );
        let mut osd = HashMap::new();
        if let Some(driver) = &driver {
            let path = dir.join(format!("osd_cage_{name}.bin"));
            write_cage(&path, &sizes, &indices, &points);
            // OpenSubdiv's peak was 164 bytes per output face at 65M faces (measured); 170 here.
            let faces = |level: u32| (cage.num_faces() as f64) * 4f64.powi(level as i32);
            let (fit, skip): (Vec<u32>, Vec<u32>) = levels
                .iter()
                .partition(|&&l| 170.0 * faces(l) <= max_gib * GIB);
            for l in skip {
                println!(
                    "OpenSubdiv level {l} skipped: about {:.1} GiB > {max_gib} GiB (BIDEGREE_BENCH_MAX_GIB)",
                    170.0 * faces(l) / GIB
                );
            }
            osd = run_driver(driver, &path, &fit, seconds);
        }
        println!("{header}");
        let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
        for &level in &levels {
            let reference = osd.get(&level);
            if let Some(o) = reference {
                println!(
                    "{:>5} {:>5} {:<14} {:>10} {:>11.3e} {:>11.3e} {:>8} {:>8}   (topology {:.1} ms, peak RSS {:.0} MiB)",
                    name,
                    level,
                    "opensubdiv",
                    o.faces,
                    o.faces as f64 / o.fresh_ms * 1e3,
                    o.faces as f64 / o.cached_ms * 1e3,
                    "1.00",
                    "1.00",
                    o.topology_ms,
                    o.peak_rss_mib
                );
            }
            let schemes = [
                ("classic 3", Rules::Classic, 3),
                ("averaging 3", Rules::Averaging, 3),
                ("averaging 4", Rules::Averaging, 4),
                ("averaging 9", Rules::Averaging, 9),
            ];
            for (label, rules, degree) in schemes {
                if !schemes_wanted
                    .as_ref()
                    .is_none_or(|w| w.iter().any(|x| x == label))
                {
                    continue;
                }
                let options = Options {
                    degree,
                    levels: level,
                    rules,
                    memory_budget: (max_gib * GIB) as u64,
                    ..Options::default()
                };
                let est = estimate(&cage, &options).expect("valid options");
                let gib = est.bytes as f64 / GIB;
                if gib > max_gib {
                    println!(
                        "{:>5} {:>5} {:<14} {:>10}   skipped: estimate {gib:.1} GiB > {max_gib} GiB (BIDEGREE_BENCH_MAX_GIB)",
                        name, level, label, est.faces
                    );
                    continue;
                }
                let ratio = |ours: f64, theirs: Option<f64>| {
                    theirs.map_or("-".to_string(), |t| format!("{:.2}", t / ours))
                };
                // Each row twice: on the default pool, then on a pool of one thread (against
                // OpenSubdiv's one thread).
                for (threads, pool) in [("", &default_pool), (" 1t", &one_thread)] {
                    let (fresh, cached, copy, faces) = pool.install(|| {
                        let fresh = median_ms(seconds, || {
                            let plan = Plan::new(&cage, &options).unwrap();
                            let out = plan.evaluate(&points, 3).unwrap();
                            (plan, out)
                        });
                        let plan = Plan::new(&cage, &options).unwrap();
                        let cached = median_ms(seconds, || plan.evaluate(&moved, 3).unwrap());
                        // The reference of "memory speed": a copy of the output into a new
                        // vector (what a cached evaluation returns).
                        let out = plan.evaluate(&moved, 3).unwrap();
                        let copy = median_ms(seconds, || out.clone());
                        (fresh, cached, copy, plan.num_output_faces() as f64)
                    });
                    if let Some(o) = reference {
                        assert_eq!(
                            o.faces as f64, faces,
                            "same output face count as OpenSubdiv"
                        );
                    }
                    println!(
                        "{:>5} {:>5} {:<14} {:>10} {:>11.3e} {:>11.3e} {:>8} {:>8} {:>8.2}",
                        name,
                        level,
                        format!("{label}{threads}"),
                        faces,
                        faces / fresh * 1e3,
                        faces / cached * 1e3,
                        ratio(fresh, reference.map(|o| o.fresh_ms)),
                        ratio(cached, reference.map(|o| o.cached_ms)),
                        cached / copy,
                    );
                    std::io::stdout().flush().ok();
                }
            }
        }
    }
    if std::env::var("BIDEGREE_BENCH_LIMIT").as_deref() != Ok("0") {
        limit_rows(&levels, seconds);
        hard_limit_rows(seconds);
    }
    println!("\nload average at the end: {}", load_average());
}

// ---------------------------------------------------------------------------------------------
// Limit rows (issue 16, engineer "limits"): kept apart from the OpenSubdiv table above.

/// The limit rows of the module documentation.
fn limit_rows(levels: &[u32], seconds: f64) {
    let (cage, _, _, points) = ico_quad_sphere(8);
    println!(
        "\nlimit surface, cage 4k (load average {}): ratios of times, limit/eval = cached \
         limit_surface / cached evaluate (target <= 2), first/fresh = Plan::new + limit_surface \
         / Plan::new + evaluate (target <= 3)",
        load_average()
    );
    println!(
        "{:>5} {:>6} {:>10} {:>10} {:>10} {:>10} {:>10} {:>11} {:>5}",
        "level",
        "degree",
        "eval ms",
        "limit ms",
        "fresh ms",
        "first ms",
        "limit/eval",
        "first/fresh",
        "extra"
    );
    let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
    for &level in levels.iter().filter(|&&l| l <= 3) {
        for degree in 2..=9 {
            let options = Options {
                degree,
                levels: level,
                ..Options::default()
            };
            let plan = Plan::new(&cage, &options).unwrap();
            let Ok(extra) = plan.limit_extra_levels() else {
                println!("{level:>5} {degree:>6}   limit refused (memory budget)");
                continue;
            };
            let eval = median_ms(seconds, || plan.evaluate(&moved, 3).unwrap());
            let limit = median_ms(seconds, || plan.limit_surface(&moved).unwrap());
            let fresh = median_ms(seconds, || {
                let plan = Plan::new(&cage, &options).unwrap();
                let out = plan.evaluate(&points, 3).unwrap();
                (plan, out)
            });
            let first = median_ms(seconds, || {
                let plan = Plan::new(&cage, &options).unwrap();
                let out = plan.limit_surface(&points).unwrap();
                (plan, out)
            });
            println!(
                "{level:>5} {degree:>6} {eval:>10.2} {limit:>10.2} {fresh:>10.2} {first:>10.2} \
                 {:>10.2} {:>11.2} {extra:>5}",
                limit / eval,
                first / fresh
            );
            std::io::stdout().flush().ok();
        }
    }
}

/// The hard limit rows of the module documentation.
fn hard_limit_rows(seconds: f64) {
    println!(
        "\nlimit surface, hard cases at level 2 (load average {}): semi/sharp = the 12 x 12 grid \
         with a crease of sharpness 7.5 / the same crease infinitely sharp (target <= 1); \
         first = Plan::new + limit_surface",
        load_average()
    );
    println!(
        "{:>6} {:>14} {:>14} {:>10} {:>14} {:>14} {:>10}",
        "degree",
        "semi ms",
        "sharp ms",
        "semi/sharp",
        "semi first ms",
        "sharp first ms",
        "semi/sharp"
    );
    let options = |degree| Options {
        degree,
        levels: 2,
        ..Options::default()
    };
    // Cached and first-call limit times of one cage.
    let times = |(cage, points): &(bidegree::Cage, Vec<f32>), degree: u32| {
        let plan = Plan::new(cage, &options(degree)).unwrap();
        let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
        plan.limit_surface(points).unwrap();
        let cached = median_ms(seconds, || plan.limit_surface(&moved).unwrap());
        let first = median_ms(seconds, || {
            let plan = Plan::new(cage, &options(degree)).unwrap();
            let out = plan.limit_surface(points).unwrap();
            (plan, out)
        });
        (cached, first)
    };
    let (semi, sharp) = (creased_grid(12, 7.5), creased_grid(12, 10.0));
    for degree in [3, 4, 9] {
        let (semi_cached, semi_first) = times(&semi, degree);
        let (sharp_cached, sharp_first) = times(&sharp, degree);
        println!(
            "{degree:>6} {semi_cached:>14.2} {sharp_cached:>14.2} {:>10.2} {semi_first:>14.2} \
             {sharp_first:>14.2} {:>10.2}",
            semi_cached / sharp_cached,
            semi_first / sharp_first
        );
        std::io::stdout().flush().ok();
    }
    println!(
        "{:>16} {:>10} {:>10}",
        "cage, degree 9", "first ms", "cached ms"
    );
    for (name, cage) in [("fan 400", triangle_fan(400)), ("1000-gon", polygon(1000))] {
        let (cached, first) = times(&cage, 9);
        println!("{name:>16} {first:>10.2} {cached:>10.2}");
        std::io::stdout().flush().ok();
    }
}
