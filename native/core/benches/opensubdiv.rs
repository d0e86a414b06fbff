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
//! OpenSubdiv's for the same cage and level (> 1: bidegree faster).
//!
//! Environment: `BIDEGREE_OSD_DRIVER` (path of the driver; without it only bidegree's numbers
//! are printed), `BIDEGREE_BENCH_SECONDS` (target time per measurement, default 1),
//! `BIDEGREE_BENCH_MAX_GIB` (skip a row whose memory estimate exceeds this, default 13: the
//! crate's `estimate`, which assumes f64 evaluation buffers, says 12.4 GiB for the 250k cage at
//! level 4 where the measured peak RSS of this bench was 7.9 GiB; OpenSubdiv's was 9.9 GiB),
//! `BIDEGREE_BENCH_CAGES` (e.g. `4k` or `4k,250k`), `BIDEGREE_BENCH_LEVELS` (e.g. `2,3`),
//! `BIDEGREE_BENCH_SCHEMES` (e.g. `classic 3,averaging 4`).

use std::collections::HashMap;
use std::hint::black_box;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use bidegree::{estimate, Cage, Options, Plan, Rules};

/// The icosahedron's triangles split into quads, each quad an `n x n` grid on the unit sphere.
/// Returns the cage, its face sizes and indices (for the driver's file) and the points.
fn ico_quad_sphere(n: usize) -> (Cage, Vec<u32>, Vec<u32>, Vec<f32>) {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut ico: Vec<[f64; 3]> = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-phi, phi] {
            ico.push([0.0, a, b]);
            ico.push([a, b, 0.0]);
            ico.push([b, 0.0, a]);
        }
    }
    let sub = |p: [f64; 3], q: [f64; 3]| [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let dot = |p: [f64; 3], q: [f64; 3]| p[0] * q[0] + p[1] * q[1] + p[2] * q[2];
    let cross = |p: [f64; 3], q: [f64; 3]| {
        [
            p[1] * q[2] - p[2] * q[1],
            p[2] * q[0] - p[0] * q[2],
            p[0] * q[1] - p[1] * q[0],
        ]
    };
    let adjacent =
        |i: usize, j: usize| (dot(sub(ico[i], ico[j]), sub(ico[i], ico[j])) - 4.0).abs() < 1e-9;
    // Base quad mesh: icosahedron vertices, edge midpoints, triangle centres.
    let mut base: Vec<[f64; 3]> = ico.clone();
    let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
    let mut quads: Vec<[usize; 4]> = Vec::new();
    for i in 0..12 {
        for j in i + 1..12 {
            for k in j + 1..12 {
                if !(adjacent(i, j) && adjacent(j, k) && adjacent(i, k)) {
                    continue;
                }
                let mut t = [i, j, k];
                let normal = cross(sub(ico[j], ico[i]), sub(ico[k], ico[i]));
                if dot(normal, ico[i]) < 0.0 {
                    t.swap(1, 2);
                }
                let centre = base.len();
                base.push(std::array::from_fn(|c| {
                    (ico[i][c] + ico[j][c] + ico[k][c]) / 3.0
                }));
                let mut midpoint = |a: usize, b: usize| {
                    *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        base.push(std::array::from_fn(|c| (ico[a][c] + ico[b][c]) / 2.0));
                        base.len() - 1
                    })
                };
                for s in 0..3 {
                    let (prev, v, next) = (t[(s + 2) % 3], t[s], t[(s + 1) % 3]);
                    quads.push([v, midpoint(v, next), centre, midpoint(prev, v)]);
                }
            }
        }
    }
    assert_eq!((base.len(), quads.len()), (62, 60));
    // Grid points keyed by the base element they lie on, so that shared edges share points.
    #[derive(Hash, PartialEq, Eq)]
    enum Key {
        Vertex(usize),
        Edge(usize, usize, usize),
        Inside(usize, usize, usize),
    }
    let mut index: HashMap<Key, u32> = HashMap::new();
    let mut points: Vec<f32> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    let lerp = |p: [f64; 3], q: [f64; 3], t: f64| -> [f64; 3] {
        std::array::from_fn(|c| p[c] + t * (q[c] - p[c]))
    };
    for (qi, q) in quads.iter().enumerate() {
        let corner = [q[0], q[1], q[2], q[3]];
        let mut id = |i: usize, j: usize| -> u32 {
            // Quad parameter (i, j): i along q0 -> q1, j along q0 -> q3.
            let along = |a: usize, b: usize, t: usize| {
                if a < b {
                    (
                        Key::Edge(a, b, t),
                        lerp(base[a], base[b], t as f64 / n as f64),
                    )
                } else {
                    (
                        Key::Edge(b, a, n - t),
                        lerp(base[b], base[a], (n - t) as f64 / n as f64),
                    )
                }
            };
            let (key, p) = match (i, j) {
                (0, 0) => (Key::Vertex(corner[0]), base[corner[0]]),
                (i, 0) if i == n => (Key::Vertex(corner[1]), base[corner[1]]),
                (i, j) if i == n && j == n => (Key::Vertex(corner[2]), base[corner[2]]),
                (0, j) if j == n => (Key::Vertex(corner[3]), base[corner[3]]),
                (i, 0) => along(corner[0], corner[1], i),
                (i, j) if i == n => along(corner[1], corner[2], j),
                (i, j) if j == n => along(corner[3], corner[2], i),
                (0, j) => along(corner[0], corner[3], j),
                (i, j) => {
                    let (u, v) = (i as f64 / n as f64, j as f64 / n as f64);
                    let bottom = lerp(base[corner[0]], base[corner[1]], u);
                    let top = lerp(base[corner[3]], base[corner[2]], u);
                    (Key::Inside(qi, i, j), lerp(bottom, top, v))
                }
            };
            *index.entry(key).or_insert_with(|| {
                let len = dot(p, p).sqrt();
                points.extend(p.iter().map(|&x| (x / len) as f32));
                (points.len() / 3 - 1) as u32
            })
        };
        for i in 0..n {
            for j in 0..n {
                for (a, b) in [(i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1)] {
                    indices.push(id(a, b));
                }
            }
        }
    }
    let sizes = vec![4u32; indices.len() / 4];
    let cage = Cage::from_indices(
        points.len() / 3,
        &sizes.iter().map(|&s| s as i64).collect::<Vec<_>>(),
        &indices.iter().map(|&v| v as i64).collect::<Vec<_>>(),
    )
    .expect("the generated cage is a valid closed quad mesh");
    (cage, sizes, indices, points)
}

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
        "{:>5} {:>5} {:<14} {:>10} {:>11} {:>11} {:>8} {:>8}",
        "cage", "level", "scheme", "faces", "fresh f/s", "cached f/s", "fresh x", "cached x"
    );
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
                let fresh = median_ms(seconds, || {
                    let plan = Plan::new(&cage, &options).unwrap();
                    let out = plan.evaluate(&points, 3).unwrap();
                    (plan, out)
                });
                let plan = Plan::new(&cage, &options).unwrap();
                let cached = median_ms(seconds, || plan.evaluate(&moved, 3).unwrap());
                let faces = plan.num_output_faces() as f64;
                drop(plan);
                let ratio = |ours: f64, theirs: Option<f64>| {
                    theirs.map_or("-".to_string(), |t| format!("{:.2}", t / ours))
                };
                if let Some(o) = reference {
                    assert_eq!(
                        o.faces as f64, faces,
                        "same output face count as OpenSubdiv"
                    );
                }
                println!(
                    "{:>5} {:>5} {:<14} {:>10} {:>11.3e} {:>11.3e} {:>8} {:>8}",
                    name,
                    level,
                    label,
                    faces,
                    faces / fresh * 1e3,
                    faces / cached * 1e3,
                    ratio(fresh, reference.map(|o| o.fresh_ms)),
                    ratio(cached, reference.map(|o| o.cached_ms)),
                );
                std::io::stdout().flush().ok();
            }
        }
    }
    println!("\nload average at the end: {}", load_average());
}
