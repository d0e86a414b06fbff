//! `cargo bench -p bidegree --bench opensubdiv` (normally through `scripts/bench_opensubdiv.sh`,
//! which builds the OpenSubdiv driver and sets `BIDEGREE_OSD_DRIVER`): output faces per second
//! of bidegree next to OpenSubdiv's own uniform refinement of the same cage, in the same run.
//!
//! Cages: an icosahedron whose 20 triangles are each split into 3 quads (60 quads; 12 vertices
//! of valence 5, 20 of valence 3), every quad an n x n grid, projected to the unit sphere: closed,
//! all quads, 32 extraordinary vertices. n = 8 gives 3,840 quads, n = 65 gives 253,500.
//!
//! Rows: bidegree classic Catmull-Clark (degree 3, `Rules::Classic`) and averaging degrees 3, 4
//! and 9, at levels 2, 3 and 4, then OpenSubdiv catmark (edge-only boundaries, no creases;
//! `bench/opensubdiv/driver.cpp`). "fresh" is everything from the cage (OpenSubdiv: refiner
//! factory + RefineUniform + PrimvarRefiner::Interpolate; bidegree: Plan::new + evaluate),
//! "cached" only the points through existing topology (Interpolate; Plan::evaluate). Each
//! bidegree row is measured twice: on rayon's default pool, then (suffix `1t`) on a pool of one
//! thread, against OpenSubdiv's one thread. The ratios are bidegree's faces/s over OpenSubdiv's
//! for the same cage and level (> 1: bidegree faster); `/copy` is the cached time over that of
//! copying the output into a new vector (1: memory speed).
//!
//! How a ratio is measured (issue 16: on the shared 2-core machine the speed of either side drifts
//! by more than 2x within minutes, so times taken apart do not divide): the sides run in
//! interleaved rounds, each round one sample of every side, the order reversed every other round
//! (fresh: default pool, OpenSubdiv, one thread; cached: copy, default pool, OpenSubdiv, one
//! thread). A round goes through every row of a table before the next round starts, so a row's
//! rounds are spread over the whole table's run rather than the few seconds the row alone takes;
//! the cached data of a row (plan, OpenSubdiv's refiner) is made again each round, untimed (on the
//! 250k cage that is seconds a row and round). A sample is the median of 3 to 21 calls taking about
//! `BIDEGREE_BENCH_SECONDS` / rounds (one call when a call is longer; only a side's first sample
//! has a warm-up). The ratio column is the median over the rounds of the ratio of the round's two
//! samples, the range column its lowest and highest; the faces/s columns come from each side's
//! median sample, so they need not divide to the ratio. OpenSubdiv's driver stays up for the cage
//! (requests on its stdin); its row closes each level, the medians of all its samples of the level.
//! Each table ends with the 1-minute load average after each round.
//!
//! Environment: `BIDEGREE_OSD_DRIVER` (path of the driver; without it only bidegree's numbers
//! are printed), `BIDEGREE_BENCH_SECONDS` (time per side of a ratio over all its rounds, default
//! 1), `BIDEGREE_BENCH_ROUNDS` (default 7), `BIDEGREE_BENCH_MAX_GIB` (skip a row whose memory
//! estimate exceeds this, default 13: the crate's `estimate`, which assumes f64 evaluation
//! buffers, says 12.4 GiB for the 250k cage at level 4 where the measured peak RSS of this bench
//! was 7.9 GiB; OpenSubdiv's was 9.9 GiB; OpenSubdiv's cached side is left out of a row when both
//! sides' cached data together exceed it), `BIDEGREE_BENCH_CAGES` (e.g. `4k` or `4k,250k`),
//! `BIDEGREE_BENCH_LEVELS` (e.g. `2,3`), `BIDEGREE_BENCH_SCHEMES` (e.g. `classic 3,averaging
//! 4`), `BIDEGREE_BENCH_LIMIT` (`0` skips the limit rows), `BIDEGREE_BENCH_LIMIT_DEGREES` (the
//! limit rows' degrees, e.g. `3,4`; default 2 to 9).
//!
//! Limit rows (issue 16, [`limit_rows`]): on the 4k cage, averaging degrees 2..9 at the
//! benchmark's levels (4 skipped: minutes per row), `Plan::limit_surface` (positions and
//! normals) against `Plan::evaluate` of the same plan, both cached ("limit/eval", target
//! <= 2), and the first call (`Plan::new` + `limit_surface`, the limit masks already cached in
//! the process) against a fresh `Plan::new` + `evaluate` ("first/fresh", target <= 3), each
//! pair in interleaved rounds as above. The cached `Plan::limit_positions` (positions alone,
//! "pos/eval") and the cached `limit_surface` with one normal per vertex
//! (`NormalDomain::Vertex`, "vtx/eval") are timed in the same rounds: the differences are what
//! the normals cost, one per output corner by default (four times the positions' bytes on a
//! quad mesh). The first `limit_positions` (`Plan::new` + `limit_positions`, "pfirst/fresh") is
//! the add-on's first update with its default *Limit Positions*.
//! In instructions (`examples/callgrind.rs`, one thread, level 3; 2026-12-03, lim16b) the first
//! call costs 5.0x (degree 3), 6.0x (4) and 14x (9) a fresh evaluation (10.5x, 13.1x and 27x
//! before the chunked stencil walk), the cached one 4.3x, 2.7x and 6.9x a cached evaluation (5.5x,
//! 3.2x and 7.4x before); see the README's limit paragraph.
//!
//! Hard limit rows ([`hard_limit_rows`]): the other limit targets in wall time, the
//! cages of the callgrind driver's `limit-*` cases at level 2: a 12 x 12 grid with one crease
//! of sharpness 7.5 against the same crease infinitely sharp ("semi/sharp", target <= 1, cached
//! and first call, each pair in interleaved rounds), and the first call of a valence-400
//! triangle fan and of a single 1000-gon at degree 9 (target under 1 s; one sample each).

use std::collections::HashMap;
use std::hint::black_box;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, ChildStdout, Command, Stdio};
use std::time::Instant;

use bidegree::{estimate, NormalDomain, Options, Plan, Rules};

mod allocator;
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

/// One answer of the driver: a sample of OpenSubdiv's fresh or cached refinement.
struct OsdSample {
    faces: u64,
    ms: f64,
    /// Create + RefineUniform alone (fresh samples only).
    topology_ms: Option<f64>,
    peak_rss_mib: f64,
}

/// The OpenSubdiv driver running on one cage, timing one request at a time (its protocol is in
/// `bench/opensubdiv/driver.cpp`), so that its samples can alternate with bidegree's.
struct Driver {
    child: Child,
    /// `None` once closed, which ends the driver.
    input: Option<ChildStdin>,
    output: BufReader<ChildStdout>,
}

impl Driver {
    /// Starts `driver` on the cage file `cage`.
    fn start(driver: &Path, cage: &Path) -> Driver {
        let mut child = Command::new(driver)
            .arg(cage)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap_or_else(|e| panic!("cannot run {}: {e}", driver.display()));
        let input = child.stdin.take();
        let output = BufReader::new(child.stdout.take().expect("the driver's stdout"));
        Driver {
            child,
            input,
            output,
        }
    }

    /// Sends one request line and returns the `key=value` fields of the answer.
    fn request(&mut self, line: &str) -> HashMap<String, f64> {
        let input = self.input.as_mut().expect("the driver is running");
        let mut answer = String::new();
        let ok = writeln!(input, "{line}").is_ok()
            && input.flush().is_ok()
            && self.output.read_line(&mut answer).is_ok_and(|n| n > 0);
        if !ok {
            panic!(
                "the OpenSubdiv driver stopped at {line:?} ({:?})",
                self.child.wait()
            );
        }
        answer
            .split_whitespace()
            .filter_map(|kv| kv.split_once('='))
            .filter_map(|(k, v)| Some((k.to_string(), v.parse().ok()?)))
            .collect()
    }

    /// A sample of `mode` (`fresh` or `cached`) at `level` of about `seconds`.
    fn sample(&mut self, mode: &str, level: u32, seconds: f64) -> OsdSample {
        let fields = self.request(&format!("{mode} {level} {seconds}"));
        let get = |k: &str| *fields.get(k).expect("a field of the driver's answer");
        OsdSample {
            faces: get("faces") as u64,
            ms: get("ms"),
            topology_ms: fields.get("topology_ms").copied(),
            peak_rss_mib: get("peak_rss_mib"),
        }
    }

    /// Drops the refiner the driver keeps for `cached` samples.
    fn release(&mut self) {
        self.request("release");
    }
}

impl Drop for Driver {
    fn drop(&mut self) {
        // Closing its stdin ends the driver; waiting reaps it.
        self.input = None;
        self.child.wait().ok();
    }
}

/// Repetitions of a call of `call_ms` in a sample of about `seconds`: one when a call is longer,
/// else 3 to 21 (a short median).
fn repetitions(call_ms: f64, seconds: f64) -> usize {
    if call_ms > seconds * 1e3 {
        1
    } else {
        ((seconds * 1e3 / call_ms.max(1e-3)) as usize).clamp(3, 21)
    }
}

/// The median of `values` (not empty).
fn median(values: &[f64]) -> f64 {
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Samples of one kind of call; it keeps the last sample's median to size the next sample, so
/// only the first sample warms up (the driver does the same).
#[derive(Default)]
struct Sampler {
    call_ms: Option<f64>,
}

impl Sampler {
    /// Median wall time (ms) of `f` over [`repetitions`] calls; the value `f` returns is dropped
    /// outside the timed region (as the driver does). A warm-up longer than `seconds` counts as
    /// the sample (keeps the big rows short).
    fn sample<R>(&mut self, seconds: f64, mut f: impl FnMut() -> R) -> f64 {
        let mut once = || {
            let t = Instant::now();
            let r = f();
            let ms = t.elapsed().as_secs_f64() * 1e3;
            drop(black_box(r));
            ms
        };
        let mut times = Vec::new();
        let call_ms = self.call_ms.unwrap_or_else(|| {
            let warmup = once();
            if warmup > seconds * 1e3 {
                times.push(warmup);
            }
            warmup
        });
        while times.len() < repetitions(call_ms, seconds) {
            times.push(once());
        }
        let ms = median(&times);
        self.call_ms = Some(ms);
        ms
    }
}

/// One side of an interleaved measurement: takes a sample and returns its time (ms).
type Side<'a> = Box<dyn FnMut() -> f64 + 'a>;

/// Round `round` of an interleaved measurement: a sample of every side, in the given order in
/// even rounds and in reverse in odd ones (so no side always runs right after a given other).
/// Returns the samples in the sides' order.
fn round(round: usize, mut sides: Vec<Side>) -> Vec<f64> {
    let n = sides.len();
    let mut samples = vec![0.0; n];
    for k in 0..n {
        let i = if round.is_multiple_of(2) {
            k
        } else {
            n - 1 - k
        };
        samples[i] = sides[i]();
    }
    samples
}

/// Runs `rounds` rounds of `each` (given the round) and returns the 1-minute load average after
/// each; says on stderr how far it got.
fn run_rounds(what: &str, rounds: usize, mut each: impl FnMut(usize)) -> Vec<String> {
    let start = Instant::now();
    (0..rounds)
        .map(|r| {
            each(r);
            let load = load_now();
            eprintln!(
                "[opensubdiv bench] {what}: round {}/{rounds} done after {:.0} s, load {load}",
                r + 1,
                start.elapsed().as_secs_f64()
            );
            load
        })
        .collect()
}

/// The per-round ratios `numerator[r] / denominator[r]` of two sides: median and range.
struct Ratio {
    median: f64,
    min: f64,
    max: f64,
}

impl Ratio {
    /// The ratios of the samples of the same round.
    fn of(numerator: &[f64], denominator: &[f64]) -> Ratio {
        let ratios: Vec<f64> = numerator
            .iter()
            .zip(denominator)
            .map(|(n, d)| n / d)
            .collect();
        Ratio {
            median: median(&ratios),
            min: ratios.iter().copied().fold(f64::INFINITY, f64::min),
            max: ratios.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }

    /// The median, or "-" without a ratio.
    fn show(ratio: Option<&Ratio>) -> String {
        ratio.map_or("-".into(), |r| format!("{:.2}", r.median))
    }

    /// The range `min-max`, or "-" without a ratio.
    fn range(ratio: Option<&Ratio>) -> String {
        ratio.map_or("-".into(), |r| format!("{:.2}-{:.2}", r.min, r.max))
    }
}

/// How each ratio is measured: `rounds` interleaved rounds of samples of about `sample_s`.
#[derive(Clone, Copy)]
struct Rounds {
    rounds: usize,
    sample_s: f64,
}

/// The 1, 5 and 15 minute load averages (Linux), or "unknown".
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .map(|s| s.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_else(|| "unknown".into())
}

/// The 1 minute load average (Linux), or "-".
fn load_now() -> String {
    load_average()
        .split_whitespace()
        .next()
        .filter(|s| *s != "unknown")
        .unwrap_or("-")
        .to_string()
}

const GIB: f64 = (1u64 << 30) as f64;

/// OpenSubdiv's peak was 164 bytes per output face at 65M faces (measured); 170 here.
const OSD_BYTES_PER_FACE: f64 = 170.0;

fn env_list<T: std::str::FromStr>(name: &str) -> Option<Vec<T>> {
    std::env::var(name)
        .ok()
        .map(|s| s.split(',').filter_map(|x| x.trim().parse().ok()).collect())
}

/// OpenSubdiv's samples of one level, gathered over the rows they were interleaved with.
#[derive(Default)]
struct OsdLevel {
    faces: u64,
    fresh: Vec<f64>,
    cached: Vec<f64>,
    topology: Vec<f64>,
    peak_rss_mib: f64,
}

impl OsdLevel {
    /// Keeps a sample's face count, topology time and peak; returns its time.
    fn note(&mut self, s: OsdSample) -> f64 {
        self.faces = s.faces;
        self.topology.extend(s.topology_ms);
        self.peak_rss_mib = self.peak_rss_mib.max(s.peak_rss_mib);
        s.ms
    }
}

fn main() {
    let seconds: f64 = std::env::var("BIDEGREE_BENCH_SECONDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1.0);
    let rounds: usize = std::env::var("BIDEGREE_BENCH_ROUNDS")
        .ok()
        .and_then(|s| s.parse().ok())
        .filter(|&r| r > 0)
        .unwrap_or(7);
    let timing = Rounds {
        rounds,
        sample_s: seconds / rounds as f64,
    };
    let max_gib: f64 = std::env::var("BIDEGREE_BENCH_MAX_GIB")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(13.0);
    let levels: Vec<u32> = env_list("BIDEGREE_BENCH_LEVELS").unwrap_or_else(|| vec![2, 3, 4]);
    let cages: Vec<String> =
        env_list("BIDEGREE_BENCH_CAGES").unwrap_or_else(|| vec!["4k".into(), "250k".into()]);
    let schemes_wanted: Option<Vec<String>> = env_list("BIDEGREE_BENCH_SCHEMES");
    let driver_path = std::env::var_os("BIDEGREE_OSD_DRIVER").map(PathBuf::from);
    match &driver_path {
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
    let driver_path = driver_path.filter(|d| d.is_file());
    let dir = PathBuf::from(option_env!("CARGO_TARGET_TMPDIR").unwrap_or("/tmp"));
    println!(
        "{} rayon threads (OpenSubdiv's Far refinement is single-threaded); load average {}; \
         ratio = bidegree faces/s / OpenSubdiv faces/s, the median over {rounds} rounds that \
         alternate the sides' samples (about {:.2} s each), a round going through all rows \
         before the next; range = the rounds' lowest-highest ratio; faces/s from each side's \
         median sample",
        rayon::current_num_threads(),
        load_average(),
        timing.sample_s
    );
    let header = format!(
        "{:>5} {:>5} {:<14} {:>10} {:>11} {:>11} {:>8} {:>8} {:>8} {:>13} {:>13} {:>13}",
        "cage",
        "level",
        "scheme",
        "faces",
        "fresh f/s",
        "cached f/s",
        "fresh x",
        "cached x",
        "/copy",
        "fresh range",
        "cached range",
        "/copy range"
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
        let osd_gib = |level: u32| {
            OSD_BYTES_PER_FACE * (cage.num_faces() as f64) * 4f64.powi(level as i32) / GIB
        };
        let mut driver = driver_path.as_ref().map(|d| {
            let path = dir.join(format!("osd_cage_{name}.bin"));
            write_cage(&path, &sizes, &indices, &points);
            Driver::start(d, &path)
        });
        if driver.is_some() {
            for &l in levels.iter().filter(|&&l| osd_gib(l) > max_gib) {
                println!(
                    "OpenSubdiv level {l} skipped: about {:.1} GiB > {max_gib} GiB (BIDEGREE_BENCH_MAX_GIB)",
                    osd_gib(l)
                );
            }
        }
        let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
        let bench = Bench {
            cage: &cage,
            points: &points,
            moved: &moved,
            pools: [&default_pool, &one_thread],
            sample_s: timing.sample_s,
        };
        let mut rows = Vec::new();
        for &level in &levels {
            let schemes = [
                ("classic 3", Rules::Classic, 3),
                ("averaging 3", Rules::Averaging, 3),
                ("averaging 4", Rules::Averaging, 4),
                ("averaging 5", Rules::Averaging, 5),
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
                let osd_fresh = driver.is_some() && osd_gib(level) <= max_gib;
                // Both sides keep their cached data while the cached samples alternate.
                let osd_cached = osd_fresh && osd_gib(level) + gib <= max_gib;
                if osd_fresh && !osd_cached {
                    println!(
                        "{:>5} {:>5} {:<14} {:>10}   cached x not measured: OpenSubdiv and bidegree \
                         together about {:.1} GiB > {max_gib} GiB (BIDEGREE_BENCH_MAX_GIB)",
                        name,
                        level,
                        label,
                        est.faces,
                        osd_gib(level) + gib
                    );
                }
                rows.push(SchemeRow::new(label, options, osd_fresh, osd_cached));
            }
        }
        let mut osd: HashMap<u32, OsdLevel> = HashMap::new();
        let loads = run_rounds(&format!("cage {name}"), rounds, |r| {
            for row in &mut rows {
                let level = osd.entry(row.options.levels).or_default();
                row.round(r, &bench, driver.as_mut(), level);
            }
        });
        println!("{header}");
        for &level in &levels {
            for row in rows.iter().filter(|row| row.options.levels == level) {
                row.print(name);
            }
            let Some(o) = osd.get(&level).filter(|o| !o.fresh.is_empty()) else {
                continue;
            };
            let per_s = |ms: &[f64]| {
                if ms.is_empty() {
                    "-".to_string()
                } else {
                    format!("{:.3e}", o.faces as f64 / median(ms) * 1e3)
                }
            };
            println!(
                "{:>5} {:>5} {:<14} {:>10} {:>11} {:>11} {:>8} {:>8}   (medians of its {} samples above; topology {:.1} ms)",
                name,
                level,
                "opensubdiv",
                o.faces,
                per_s(&o.fresh),
                per_s(&o.cached),
                "1.00",
                "1.00",
                o.fresh.len() + o.cached.len(),
                median(&o.topology)
            );
        }
        if let Some(peak) = osd.values().map(|o| o.peak_rss_mib).reduce(f64::max) {
            println!("OpenSubdiv driver's peak RSS: {peak:.0} MiB (its largest level)");
        }
        println!("load average (1 min) after each round: {}", loads.join(" "));
    }
    if std::env::var("BIDEGREE_BENCH_LIMIT").as_deref() != Ok("0") {
        let degrees = env_list("BIDEGREE_BENCH_LIMIT_DEGREES").unwrap_or_else(|| (2..=9).collect());
        limit_rows(&levels, &degrees, timing);
        hard_limit_rows(timing, seconds);
    }
    println!("\nload average at the end: {}", load_average());
}

/// What the rows of the OpenSubdiv table measure on.
struct Bench<'a> {
    cage: &'a bidegree::Cage,
    points: &'a [f32],
    /// The points moved, for cached evaluations.
    moved: &'a [f32],
    /// Rayon's default pool and a pool of one thread.
    pools: [&'a rayon::ThreadPool; 2],
    sample_s: f64,
}

impl Bench<'_> {
    /// A side timing fresh subdivision (`Plan::new` + `evaluate`) on `pool`.
    fn fresh_side<'b>(
        &'b self,
        options: &'b Options,
        pool: &'b rayon::ThreadPool,
        sampler: &'b mut Sampler,
    ) -> Side<'b> {
        Box::new(move || {
            pool.install(|| {
                sampler.sample(self.sample_s, || {
                    let plan = Plan::new(self.cage, options).unwrap();
                    let out = plan.evaluate(self.points, 3).unwrap();
                    (plan, out)
                })
            })
        })
    }

    /// A side timing `plan.evaluate` (cached) on `pool`.
    fn cached_side<'b>(
        &'b self,
        plan: &'b Plan,
        pool: &'b rayon::ThreadPool,
        sampler: &'b mut Sampler,
    ) -> Side<'b> {
        Box::new(move || {
            pool.install(|| sampler.sample(self.sample_s, || plan.evaluate(self.moved, 3).unwrap()))
        })
    }
}

/// One scheme at one level of the OpenSubdiv table (its two rows: default pool, one thread) and
/// its samples by round.
struct SchemeRow {
    label: &'static str,
    options: Options,
    /// OpenSubdiv takes part in the fresh samples, and in the cached ones.
    osd_fresh: bool,
    osd_cached: bool,
    faces: u64,
    /// Fresh default pool, fresh one thread, copy, cached default pool, cached one thread.
    samplers: [Sampler; 5],
    /// By pool: default, one thread.
    fresh: [Vec<f64>; 2],
    cached: [Vec<f64>; 2],
    copy: Vec<f64>,
    osd_fresh_ms: Vec<f64>,
    osd_cached_ms: Vec<f64>,
}

impl SchemeRow {
    /// A row with no samples yet.
    fn new(label: &'static str, options: Options, osd_fresh: bool, osd_cached: bool) -> SchemeRow {
        SchemeRow {
            label,
            options,
            osd_fresh,
            osd_cached,
            faces: 0,
            samplers: Default::default(),
            fresh: Default::default(),
            cached: Default::default(),
            copy: Vec::new(),
            osd_fresh_ms: Vec::new(),
            osd_cached_ms: Vec::new(),
        }
    }

    /// One round: fresh samples of (default pool, OpenSubdiv, one thread), then on a new plan
    /// cached ones of (copy, default pool, OpenSubdiv, one thread), so that each bidegree sample
    /// runs next to an OpenSubdiv one. OpenSubdiv's samples are also gathered in `osd`.
    fn round(&mut self, r: usize, bench: &Bench, driver: Option<&mut Driver>, osd: &mut OsdLevel) {
        let SchemeRow {
            options,
            osd_fresh,
            osd_cached,
            faces,
            samplers,
            fresh,
            cached,
            copy,
            osd_fresh_ms,
            osd_cached_ms,
            ..
        } = self;
        let mut driver = driver.filter(|_| *osd_fresh);
        let level = options.levels;
        let sample_s = bench.sample_s;
        let [default_pool, one_thread] = bench.pools;
        let [fresh_default, fresh_one, copy_sampler, cached_default, cached_one] = samplers;

        let mut sides = vec![bench.fresh_side(options, default_pool, fresh_default)];
        let osd_at = driver.as_deref_mut().map(|d| {
            let side: Side = Box::new(|| osd.note(d.sample("fresh", level, sample_s)));
            sides.push(side);
            sides.len() - 1
        });
        sides.push(bench.fresh_side(options, one_thread, fresh_one));
        let mut samples = round(r, sides);
        if let Some(i) = osd_at {
            osd_fresh_ms.push(samples.remove(i));
            osd.fresh.push(osd_fresh_ms[r]);
        }
        fresh[0].push(samples[0]);
        fresh[1].push(samples[1]);

        let plan = default_pool.install(|| Plan::new(bench.cage, options).unwrap());
        // The reference of "memory speed": a copy of the output into a new vector (what a
        // cached evaluation returns); making it also warms the new plan up.
        let out = plan.evaluate(bench.moved, 3).unwrap();
        *faces = plan.num_output_faces() as u64;
        let mut sides: Vec<Side> = vec![
            Box::new(|| copy_sampler.sample(sample_s, || out.clone())),
            bench.cached_side(&plan, default_pool, cached_default),
        ];
        let osd_at = driver.as_deref_mut().filter(|_| *osd_cached).map(|d| {
            let side: Side = Box::new(|| osd.note(d.sample("cached", level, sample_s)));
            sides.push(side);
            sides.len() - 1
        });
        sides.push(bench.cached_side(&plan, one_thread, cached_one));
        let mut samples = round(r, sides);
        if let Some(i) = osd_at {
            osd_cached_ms.push(samples.remove(i));
            osd.cached.push(osd_cached_ms[r]);
        }
        copy.push(samples[0]);
        cached[0].push(samples[1]);
        cached[1].push(samples[2]);
        if let Some(d) = driver {
            d.release();
            assert_eq!(osd.faces, *faces, "same output face count as OpenSubdiv");
        }
    }

    /// Prints the two rows (default pool, one thread) of cage `name`.
    fn print(&self, name: &str) {
        for (t, threads) in ["", " 1t"].iter().enumerate() {
            let faces = self.faces as f64;
            let fresh = (!self.osd_fresh_ms.is_empty())
                .then(|| Ratio::of(&self.osd_fresh_ms, &self.fresh[t]));
            let cached = (!self.osd_cached_ms.is_empty())
                .then(|| Ratio::of(&self.osd_cached_ms, &self.cached[t]));
            let copy = Ratio::of(&self.cached[t], &self.copy);
            println!(
                "{:>5} {:>5} {:<14} {:>10} {:>11.3e} {:>11.3e} {:>8} {:>8} {:>8.2} {:>13} {:>13} {:>13}",
                name,
                self.options.levels,
                format!("{}{threads}", self.label),
                self.faces,
                faces / median(&self.fresh[t]) * 1e3,
                faces / median(&self.cached[t]) * 1e3,
                Ratio::show(fresh.as_ref()),
                Ratio::show(cached.as_ref()),
                copy.median,
                Ratio::range(fresh.as_ref()),
                Ratio::range(cached.as_ref()),
                Ratio::range(Some(&copy)),
            );
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Limit rows (issue 16, engineer "limits"): kept apart from the OpenSubdiv table above.

/// The limit rows of the module documentation.
fn limit_rows(levels: &[u32], degrees: &[u32], timing: Rounds) {
    let (cage, _, _, points) = ico_quad_sphere(8);
    println!(
        "\nlimit surface, cage 4k (load average {}): ratios of times, each the median of {} \
         interleaved rounds (range: lowest-highest), limit/eval = cached limit_surface / cached \
         evaluate (target <= 2), pos/eval = cached limit_positions / cached evaluate, vtx/eval \
         = cached limit_surface with normals per vertex / cached evaluate, \
         first/fresh = Plan::new + limit_surface / Plan::new + evaluate (target <= 3), \
         pfirst/fresh = Plan::new + limit_positions / Plan::new + evaluate; times are each \
         side's median sample",
        load_average(),
        timing.rounds
    );
    let Rounds { rounds, sample_s } = timing;
    let moved: Vec<f32> = points.iter().map(|x| x * 1.01).collect();
    /// One row: a plan, its samplers (eval, limit, positions, limit with vertex normals,
    /// fresh, first, first positions) and their samples by round.
    struct Row {
        options: Options,
        plan: Plan,
        extra: u32,
        samplers: [Sampler; 7],
        samples: [Vec<f64>; 7],
    }
    let mut rows = Vec::new();
    for &level in levels.iter().filter(|&&l| l <= 3) {
        for &degree in degrees {
            let options = Options {
                degree,
                levels: level,
                ..Options::default()
            };
            let plan = Plan::new(&cage, &options).unwrap();
            match plan.limit_extra_levels() {
                Ok(extra) => {
                    // The first call makes the plan's limit data: not a cached call's work.
                    plan.limit_surface(&points).unwrap();
                    rows.push(Row {
                        options,
                        plan,
                        extra,
                        samplers: Default::default(),
                        samples: Default::default(),
                    });
                }
                Err(_) => println!("{level:>5} {degree:>6}   limit refused (memory budget)"),
            }
        }
    }
    let loads = run_rounds("limit rows", rounds, |r| {
        for row in &mut rows {
            let [eval, limit, positions, vertex, fresh, first, first_positions] = &mut row.samplers;
            let (plan, options) = (&row.plan, &row.options);
            let cached = round(
                r,
                vec![
                    Box::new(|| eval.sample(sample_s, || plan.evaluate(&moved, 3).unwrap())),
                    Box::new(|| limit.sample(sample_s, || plan.limit_surface(&moved).unwrap())),
                    Box::new(|| {
                        positions.sample(sample_s, || plan.limit_positions(&moved, 3).unwrap())
                    }),
                    Box::new(|| {
                        vertex.sample(sample_s, || {
                            plan.limit_surface_with(&moved, NormalDomain::Vertex)
                                .unwrap()
                        })
                    }),
                ],
            );
            let new = round(
                r,
                vec![
                    Box::new(|| {
                        fresh.sample(sample_s, || {
                            let plan = Plan::new(&cage, options).unwrap();
                            let out = plan.evaluate(&points, 3).unwrap();
                            (plan, out)
                        })
                    }),
                    Box::new(|| {
                        first.sample(sample_s, || {
                            let plan = Plan::new(&cage, options).unwrap();
                            let out = plan.limit_surface(&points).unwrap();
                            (plan, out)
                        })
                    }),
                    Box::new(|| {
                        first_positions.sample(sample_s, || {
                            let plan = Plan::new(&cage, options).unwrap();
                            let out = plan.limit_positions(&points, 3).unwrap();
                            (plan, out)
                        })
                    }),
                ],
            );
            for (list, ms) in row.samples.iter_mut().zip(cached.into_iter().chain(new)) {
                list.push(ms);
            }
        }
    });
    println!(
        "{:>5} {:>6} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8} {:>10} {:>8} {:>8} {:>11} {:>12} \
         {:>5} {:>11} {:>11} {:>11} {:>11} {:>11}",
        "level",
        "degree",
        "eval ms",
        "limit ms",
        "pos ms",
        "vtx ms",
        "fresh ms",
        "first ms",
        "pfirst ms",
        "limit/eval",
        "pos/eval",
        "vtx/eval",
        "first/fresh",
        "pfirst/fresh",
        "extra",
        "l/e range",
        "p/e range",
        "v/e range",
        "f/f range",
        "pf/f range"
    );
    for row in &rows {
        let [eval, limit, positions, vertex, fresh, first, first_positions] = &row.samples;
        let limit_eval = Ratio::of(limit, eval);
        let positions_eval = Ratio::of(positions, eval);
        let vertex_eval = Ratio::of(vertex, eval);
        let first_fresh = Ratio::of(first, fresh);
        let positions_fresh = Ratio::of(first_positions, fresh);
        println!(
            "{:>5} {:>6} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>8.2} {:>10.2} {:>8.2} \
             {:>8.2} {:>11.2} {:>12.2} {:>5} {:>11} {:>11} {:>11} {:>11} {:>11}",
            row.options.levels,
            row.options.degree,
            median(eval),
            median(limit),
            median(positions),
            median(vertex),
            median(fresh),
            median(first),
            median(first_positions),
            limit_eval.median,
            positions_eval.median,
            vertex_eval.median,
            first_fresh.median,
            positions_fresh.median,
            row.extra,
            Ratio::range(Some(&limit_eval)),
            Ratio::range(Some(&positions_eval)),
            Ratio::range(Some(&vertex_eval)),
            Ratio::range(Some(&first_fresh)),
            Ratio::range(Some(&positions_fresh)),
        );
    }
    println!("load average (1 min) after each round: {}", loads.join(" "));
}

/// The hard limit rows of the module documentation; the fan and the polygon, which have no
/// ratio, take one sample of about `seconds` each.
fn hard_limit_rows(timing: Rounds, seconds: f64) {
    println!(
        "\nlimit surface, hard cases at level 2 (load average {}): semi/sharp = the 12 x 12 grid \
         with a crease of sharpness 7.5 / the same crease infinitely sharp (target <= 1), the \
         median of {} interleaved rounds (range: lowest-highest); first = Plan::new + \
         limit_surface",
        load_average(),
        timing.rounds
    );
    let options = |degree| Options {
        degree,
        levels: 2,
        ..Options::default()
    };
    let Rounds { rounds, sample_s } = timing;
    let moved = |points: &[f32]| points.iter().map(|x| x * 1.01).collect::<Vec<f32>>();
    let (semi, sharp) = (creased_grid(12, 7.5), creased_grid(12, 10.0));
    let (semi_moved, sharp_moved) = (moved(&semi.1), moved(&sharp.1));
    let first_call = |(cage, points): &(bidegree::Cage, Vec<f32>), degree: u32| {
        let plan = Plan::new(cage, &options(degree)).unwrap();
        let out = plan.limit_surface(points).unwrap();
        (plan, out)
    };
    /// One degree: its two plans, samplers (semi, sharp cached; semi, sharp first) and their
    /// samples by round.
    struct Row {
        degree: u32,
        plans: [Plan; 2],
        samplers: [Sampler; 4],
        samples: [Vec<f64>; 4],
    }
    let mut rows: Vec<Row> = [3, 4, 9]
        .into_iter()
        .map(|degree| Row {
            degree,
            plans: [&semi, &sharp].map(|(cage, points)| {
                let plan = Plan::new(cage, &options(degree)).unwrap();
                // The first call makes the plan's limit data: not a cached call's work.
                plan.limit_surface(points).unwrap();
                plan
            }),
            samplers: Default::default(),
            samples: Default::default(),
        })
        .collect();
    let loads = run_rounds("hard limit rows", rounds, |r| {
        for row in &mut rows {
            let [semi_cached, sharp_cached, semi_first, sharp_first] = &mut row.samplers;
            let [semi_plan, sharp_plan] = &row.plans;
            let degree = row.degree;
            let cached = round(
                r,
                vec![
                    Box::new(|| {
                        semi_cached
                            .sample(sample_s, || semi_plan.limit_surface(&semi_moved).unwrap())
                    }),
                    Box::new(|| {
                        sharp_cached
                            .sample(sample_s, || sharp_plan.limit_surface(&sharp_moved).unwrap())
                    }),
                ],
            );
            let first = round(
                r,
                vec![
                    Box::new(|| semi_first.sample(sample_s, || first_call(&semi, degree))),
                    Box::new(|| sharp_first.sample(sample_s, || first_call(&sharp, degree))),
                ],
            );
            for (list, ms) in row.samples.iter_mut().zip(cached.into_iter().chain(first)) {
                list.push(ms);
            }
        }
    });
    println!(
        "{:>6} {:>14} {:>14} {:>10} {:>14} {:>14} {:>10} {:>12} {:>12}",
        "degree",
        "semi ms",
        "sharp ms",
        "semi/sharp",
        "semi first ms",
        "sharp first ms",
        "semi/sharp",
        "cached range",
        "first range"
    );
    for row in &rows {
        let [semi_cached, sharp_cached, semi_first, sharp_first] = &row.samples;
        let cached = Ratio::of(semi_cached, sharp_cached);
        let first = Ratio::of(semi_first, sharp_first);
        println!(
            "{:>6} {:>14.2} {:>14.2} {:>10.2} {:>14.2} {:>14.2} {:>10.2} {:>12} {:>12}",
            row.degree,
            median(semi_cached),
            median(sharp_cached),
            cached.median,
            median(semi_first),
            median(sharp_first),
            first.median,
            Ratio::range(Some(&cached)),
            Ratio::range(Some(&first)),
        );
    }
    println!("load average (1 min) after each round: {}", loads.join(" "));
    println!(
        "{:>16} {:>10} {:>10}",
        "cage, degree 9", "first ms", "cached ms"
    );
    for (name, (cage, points)) in [("fan 400", triangle_fan(400)), ("1000-gon", polygon(1000))] {
        let options = options(9);
        // Cached first, so that the first call's timing finds the limit masks made (as above);
        // the call before it makes them.
        let plan = Plan::new(&cage, &options).unwrap();
        plan.limit_surface(&points).unwrap();
        let moved = moved(&points);
        let cached = Sampler::default().sample(seconds, || plan.limit_surface(&moved).unwrap());
        let first = Sampler::default().sample(seconds, || {
            let plan = Plan::new(&cage, &options).unwrap();
            let out = plan.limit_surface(&points).unwrap();
            (plan, out)
        });
        println!("{name:>16} {first:>10.2} {cached:>10.2}");
        std::io::stdout().flush().ok();
    }
}
