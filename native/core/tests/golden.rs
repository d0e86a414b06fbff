//! Golden hashes: the bits of every result the core gives (points, faces, edges, normals, UVs,
//! adaptive triangles, subdivision matrices) on a fixed set of cages, for every degree 1..9, both
//! rule sets, primal and dual output, limits and adaptive, in f32 and f64. A refactor that is
//! meant to change nothing must leave every hash as it is.
//!
//! The hashes live in `tests/golden.txt`. A change that deliberately changes results regenerates
//! them with
//!
//! ```sh
//! BIDEGREE_GOLDEN_UPDATE=1 cargo test -p bidegree --release --test golden
//! ```
//!
//! and says in its commit which hashes changed and why.

mod common;

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use bidegree::analysis::{basis_function, subdivision_matrix};
use bidegree::{
    subdivide_adaptive, AdaptiveMesh, AdaptiveOptions, Boundary, Cage, Creasing, FaceVaryingMode,
    Options, OutputKind, Plan, Result, Rules, Scalar,
};
use common::{cage, cube, Random};

/// FNV-1a over 64-bit words: a stable hash (std's hashers may change between releases).
struct Hash(u64);

impl Hash {
    fn new() -> Hash {
        Hash(0xcbf2_9ce4_8422_2325)
    }
    fn word(&mut self, x: u64) {
        for b in x.to_le_bytes() {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
    }
    fn words(&mut self, xs: impl IntoIterator<Item = u64>) {
        let mut n = 0u64;
        for x in xs {
            self.word(x);
            n += 1;
        }
        // The length separates consecutive arrays.
        self.word(n);
    }
    fn floats<T: Bits>(&mut self, xs: &[T]) {
        self.words(xs.iter().map(|x| x.bits()));
    }
    fn ints(&mut self, xs: &[u32]) {
        self.words(xs.iter().map(|&x| x as u64));
    }
    fn text(&mut self, s: &str) {
        self.words(s.bytes().map(|b| b as u64));
    }
}

/// The bit pattern of a scalar.
trait Bits: Scalar {
    fn bits(self) -> u64;
}
impl Bits for f32 {
    fn bits(self) -> u64 {
        self.to_bits() as u64
    }
}
impl Bits for f64 {
    fn bits(self) -> u64 {
        self.to_bits()
    }
}

/// A cage with its points, under a name.
struct Case {
    name: &'static str,
    cage: Cage,
    points: Vec<f64>,
}

fn jitter(points: &mut [f64], seed: u64, amount: f64) {
    let mut r = Random(seed);
    for x in points {
        *x += amount * (r.next() - 0.5);
    }
}

/// The cages: closed and open, quads, triangles and a pentagon, valences 2 to 6, infinitely
/// sharp and semi-sharp creases, corners, and isolated vertices.
fn cases() -> Vec<Case> {
    let mut out = Vec::new();

    // A cube with a semi-sharp crease loop around its top (2.5), one infinitely sharp edge
    // (10) and a corner (infinite): closed quads, valence 3.
    let (cube, mut cube_points) = cube();
    jitter(&mut cube_points, 1, 0.2);
    out.push(Case {
        name: "cube-creased",
        cage: cube
            .clone()
            .with_creases(&[
                (4, 5, 2.5),
                (5, 6, 2.5),
                (6, 7, 2.5),
                (7, 4, 2.5),
                (0, 1, 10.0),
            ])
            .unwrap()
            .with_corners(&[(2, f32::INFINITY)])
            .unwrap(),
        points: cube_points.clone(),
    });
    // The same cube with semi-sharp creases of different sharpness meeting (Chaikin differs
    // from uniform there), a fractional corner, and a dart.
    out.push(Case {
        name: "cube-semi-sharp",
        cage: cube
            .clone()
            .with_creases(&[(4, 5, 1.5), (5, 6, 0.5), (6, 7, 3.0), (0, 3, 0.7)])
            .unwrap()
            .with_corners(&[(1, 1.5)])
            .unwrap(),
        points: cube_points.clone(),
    });

    // An open patch: a pentagon in the middle, quads and triangles around it, a boundary; a
    // semi-sharp crease inside and a corner.
    //   ring of the pentagon 0..5, outer ring 5..15
    let mut points = Vec::new();
    for i in 0..5 {
        let a = 2.0 * std::f64::consts::PI * i as f64 / 5.0;
        points.extend([a.cos(), a.sin(), 0.3]);
    }
    for i in 0..10 {
        let a = 2.0 * std::f64::consts::PI * (i as f64 - 0.5) / 10.0;
        points.extend([2.2 * a.cos(), 2.2 * a.sin(), 0.0]);
    }
    jitter(&mut points, 2, 0.3);
    let mut faces = vec![vec![0, 1, 2, 3, 4]];
    for i in 0..5 {
        let j = (i + 1) % 5;
        let (o0, o1, o2) = (5 + 2 * i, 5 + 2 * i + 1, 5 + (2 * i + 2) % 10);
        faces.push(vec![o0, o1, i]);
        faces.push(vec![i, o1, o2, j]);
    }
    let open = cage(15, &faces);
    out.push(Case {
        name: "pentagon-open",
        cage: open
            .clone()
            .with_creases(&[(0, 1, 1.3), (1, 2, f32::INFINITY)])
            .unwrap()
            .with_corners(&[(3, 2.0)])
            .unwrap(),
        points: points.clone(),
    });
    out.push(Case {
        name: "pentagon-open-plain",
        cage: open,
        points,
    });

    // A closed bipyramid over a hexagon: triangles, two apexes of valence 6, ring valence 4.
    let k = 6;
    let mut points = vec![0.0, 0.0, 1.2, 0.0, 0.0, -1.0];
    for i in 0..k {
        let a = 2.0 * std::f64::consts::PI * i as f64 / k as f64;
        points.extend([a.cos(), a.sin(), 0.0]);
    }
    jitter(&mut points, 3, 0.2);
    let mut faces = Vec::new();
    for i in 0..k {
        let (a, b) = (2 + i, 2 + (i + 1) % k);
        faces.push(vec![0, a, b]);
        faces.push(vec![1, b, a]);
    }
    out.push(Case {
        name: "bipyramid-6",
        cage: cage(2 + k, &faces)
            .with_creases(&[(2, 3, 10.0), (3, 4, 10.0)])
            .unwrap(),
        points,
    });

    // A 3 x 3 grid of quads with two isolated vertices (one in the middle of the numbering, one
    // at the end), an infinitely sharp crease across and a boundary.
    let (m, n) = (3, 3);
    let id = |a: usize, b: usize| {
        let v = a * (n + 1) + b;
        // Vertex 7 is isolated: shift the grid's ids from there on.
        if v >= 7 {
            v + 1
        } else {
            v
        }
    };
    let mut faces = Vec::new();
    for a in 0..m {
        for b in 0..n {
            faces.push(vec![id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)]);
        }
    }
    let count = (m + 1) * (n + 1) + 2;
    let mut points = vec![0.0; 3 * count];
    for a in 0..=m {
        for b in 0..=n {
            let v = id(a, b);
            points[3 * v] = a as f64;
            points[3 * v + 1] = b as f64;
        }
    }
    points[3 * 7] = 9.0;
    points[3 * (count - 1) + 2] = -9.0;
    jitter(&mut points, 4, 0.4);
    out.push(Case {
        name: "grid-isolated",
        cage: cage(count, &faces)
            .with_creases(&[
                (id(1, 0) as i64, id(1, 1) as i64, 10.0),
                (id(1, 1) as i64, id(1, 2) as i64, 10.0),
                (id(1, 2) as i64, id(1, 3) as i64, 10.0),
            ])
            .unwrap(),
        points,
    });

    // Two quads glued along two edges: interior vertices of valence 2 (the dual output refuses
    // them, the hash records the refusal; the limits take the valence-2 position mask and fan
    // normals).
    let mut points = vec![
        0.0, 0.0, 0.0, 1.0, 0.0, 0.2, 1.0, 1.0, 0.0, 0.0, 1.0, 0.1, 0.5, 0.5, 1.0, 0.5, 0.5, -1.0,
    ];
    jitter(&mut points, 5, 0.1);
    out.push(Case {
        name: "valence-2",
        cage: cage(
            6,
            &[
                vec![0, 1, 4, 3],
                vec![1, 2, 3, 4],
                vec![0, 3, 5, 1],
                vec![1, 5, 3, 2],
            ],
        ),
        points,
    });
    out
}

/// Everything a plan gives for one set of points, hashed in a fixed order.
fn hash_plan<T: Bits>(h: &mut Hash, plan: &Plan, points: &[T], uvs: &[T]) {
    h.ints(plan.output_face_offsets());
    h.ints(plan.output_face_vertices());
    h.ints(plan.output_face_origin());
    h.ints(&plan.output_edges().concat());
    h.ints(plan.output_corner_edges());
    h.ints(plan.isolated_vertices());
    record(h, plan.evaluate(points, 3));
    // One and five channels (five runs in groups of four).
    let one: Vec<T> = points.iter().step_by(3).copied().collect();
    record(h, plan.evaluate(&one, 1));
    let five: Vec<T> = points
        .chunks(3)
        .flat_map(|p| [p[0], p[1], p[2], p[0] + p[1], p[2] * p[2]])
        .collect();
    record(h, plan.evaluate(&five, 5));
    record(
        h,
        plan.evaluate_face_varying(uvs, 2, FaceVaryingMode::All, false),
    );
}

/// The hash of a result: its bits, or its error message.
fn record<T: Bits>(h: &mut Hash, r: Result<Vec<T>>) {
    match r {
        Ok(v) => h.floats(&v),
        Err(e) => h.text(&e.to_string()),
    }
}

fn hash_limit<T: Bits>(h: &mut Hash, plan: &Plan, points: &[T], normals: bool) {
    match plan.limit_extra_levels() {
        Ok(m) => h.word(m as u64),
        Err(e) => h.text(&e.to_string()),
    }
    record(h, plan.limit_positions(points, 3));
    if normals {
        match plan.limit_surface(points) {
            Ok((p, n)) => {
                h.floats(&p);
                h.floats(&n);
            }
            Err(e) => h.text(&e.to_string()),
        }
    }
}

fn hash_adaptive<T: Bits>(h: &mut Hash, r: Result<AdaptiveMesh<T>>) {
    match r {
        Ok(m) => {
            h.floats(&m.points);
            h.ints(&m.triangles.concat());
            h.ints(&m.face_origin);
            h.ints(&m.triangle_level);
            h.ints(&m.vertex_level);
            h.words(m.vertex_id.iter().copied());
            h.words(m.leaves_per_level.iter().copied());
            h.words(m.max_error.map(f64::to_bits));
        }
        Err(e) => h.text(&e.to_string()),
    }
}

/// Face-varying values: one UV per cage corner, from the corner's vertex and face.
fn corner_uvs(cage: &Cage, points: &[f64]) -> Vec<f64> {
    let mut uvs = Vec::with_capacity(2 * cage.face_vertices().len());
    for f in 0..cage.num_faces() {
        let range = cage.face_offsets()[f] as usize..cage.face_offsets()[f + 1] as usize;
        for &v in &cage.face_vertices()[range] {
            let p = &points[3 * v as usize..3 * v as usize + 3];
            uvs.extend([p[0] + 0.1 * f as f64, p[1] - 0.05 * f as f64]);
        }
    }
    uvs
}

/// Every hash, by name.
fn compute() -> BTreeMap<String, u64> {
    let mut hashes = BTreeMap::new();
    let f32s = |x: &[f64]| x.iter().map(|&v| v as f32).collect::<Vec<f32>>();
    for case in cases() {
        let uvs = corner_uvs(&case.cage, &case.points);
        let (p32, uv32) = (f32s(&case.points), f32s(&uvs));
        let schemes = (1..=9u32)
            .map(|d| (d, Rules::Averaging, Creasing::Uniform))
            .chain((1..=3).map(|d| (d, Rules::Classic, Creasing::Uniform)))
            .chain([(3, Rules::Classic, Creasing::Chaikin)]);
        for (degree, rules, creasing) in schemes {
            for (output, boundary, levels) in [
                (OutputKind::Primal, Boundary::EdgeOnly, 2),
                (OutputKind::Dual, Boundary::EdgeOnly, 2),
                (OutputKind::Primal, Boundary::EdgeAndCorner, 1),
                (OutputKind::Primal, Boundary::EdgeOnly, 0),
            ] {
                let options = Options {
                    degree,
                    levels,
                    output,
                    boundary,
                    rules,
                    creasing,
                    ..Options::default()
                };
                let name = format!(
                    "{} {:?} {degree} {creasing:?} {output:?} {boundary:?} L{levels}",
                    case.name, rules
                );
                let mut h = Hash::new();
                match Plan::new(&case.cage, &options) {
                    Ok(plan) => {
                        hash_plan(&mut h, &plan, &case.points, &uvs);
                        hash_plan(&mut h, &plan, &p32, &uv32);
                        // Limits: primal, at most one level beyond the plan's on these
                        // cages' second level (the extension is the expensive part).
                        if output == OutputKind::Primal && levels == 1 {
                            let normals = rules == Rules::Averaging;
                            hash_limit(&mut h, &plan, &case.points, normals);
                            hash_limit(&mut h, &plan, &p32, normals);
                        }
                    }
                    Err(e) => h.text(&e.to_string()),
                }
                hashes.insert(name, h.0);
            }
        }
        for degree in 1..=9u32 {
            for (boundary, tolerance, measure) in [
                (Boundary::EdgeOnly, 2e-2, false),
                (Boundary::EdgeAndCorner, 5e-3, true),
                (Boundary::EdgeOnly, 0.0, false),
            ] {
                let options = AdaptiveOptions {
                    degree,
                    max_level: 3,
                    tolerance,
                    boundary,
                    measure_leaves: measure,
                    ..AdaptiveOptions::default()
                };
                let mut h = Hash::new();
                hash_adaptive(
                    &mut h,
                    subdivide_adaptive(&case.cage, &case.points, &options),
                );
                hash_adaptive(&mut h, subdivide_adaptive(&case.cage, &p32, &options));
                let name = format!(
                    "{} adaptive {degree} {boundary:?} tol {tolerance} measure {measure}",
                    case.name
                );
                hashes.insert(name, h.0);
            }
        }
    }
    // The analysis runs unit impulses through single steps of the engine.
    for degree in 1..=9u32 {
        for valence in [3, 5] {
            let mut h = Hash::new();
            match subdivision_matrix(degree, valence) {
                Ok(m) => h.floats(m.matrix.as_slice()),
                Err(e) => h.text(&e.to_string()),
            }
            hashes.insert(
                format!("subdivision matrix {degree} valence {valence}"),
                h.0,
            );
        }
    }
    for degree in [2u32, 3, 4] {
        let mut h = Hash::new();
        match basis_function(degree, 5, (0, 0, 0), 2) {
            Ok(net) => {
                for channel in &net.values {
                    for sector in channel {
                        h.floats(sector);
                    }
                }
            }
            Err(e) => h.text(&e.to_string()),
        }
        hashes.insert(format!("basis function {degree} valence 5"), h.0);
    }
    hashes
}

fn golden_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden.txt")
}

#[test]
fn results_match_the_golden_hashes() {
    let hashes = compute();
    let mut text = String::new();
    for (name, h) in &hashes {
        writeln!(text, "{h:016x} {name}").unwrap();
    }
    if std::env::var_os("BIDEGREE_GOLDEN_UPDATE").is_some() {
        std::fs::write(golden_path(), &text).unwrap();
        return;
    }
    let stored = std::fs::read_to_string(golden_path()).expect(
        "tests/golden.txt is missing: BIDEGREE_GOLDEN_UPDATE=1 cargo test -p bidegree --release --test golden",
    );
    let stored: BTreeMap<&str, &str> = stored
        .lines()
        .filter_map(|l| l.split_once(' ').map(|(h, n)| (n, h)))
        .collect();
    let mut wrong = Vec::new();
    for (name, h) in &hashes {
        match stored.get(name.as_str()) {
            Some(s) if *s == format!("{h:016x}") => {}
            Some(_) => wrong.push(format!("changed: {name}")),
            None => wrong.push(format!("new: {name}")),
        }
    }
    for name in stored.keys() {
        if !hashes.contains_key(*name) {
            wrong.push(format!("gone: {name}"));
        }
    }
    assert!(
        wrong.is_empty(),
        "{} of {} golden hashes differ:\n{}",
        wrong.len(),
        hashes.len(),
        wrong.join("\n")
    );
}
