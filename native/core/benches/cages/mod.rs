//! Cages shared by the benchmarks and the instruction-count driver (`examples/callgrind.rs`).

use std::collections::HashMap;

use bidegree::Cage;

/// The icosahedron's triangles split into quads, each quad an `n x n` grid on the unit sphere.
/// Returns the cage, its face sizes and indices (for the driver's file) and the points.
pub fn ico_quad_sphere(n: usize) -> (Cage, Vec<u32>, Vec<u32>, Vec<f32>) {
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

/// A closed disc: a fan of `valence` triangles around vertex 0 (the rim on the unit circle,
/// a boundary), the limit's worst case near one high valence.
/// UVs per corner of `ico_quad_sphere(n)` (its `indices` and `points`) with a seam around each
/// of its 60 base patches: each patch is its own island (corner `k` of face `f` is in patch
/// `f / n^2`, the cage being built patch by patch), the islands on an 8-wide grid.
#[allow(dead_code)] // the face-varying bench and the callgrind driver only
pub fn ico_patch_uvs(n: usize, indices: &[u32], points: &[f32]) -> Vec<f32> {
    indices
        .iter()
        .enumerate()
        .flat_map(|(k, &v)| {
            let patch = (k / 4 / (n * n)) as f32;
            let p = &points[3 * v as usize..][..3];
            [
                p[0] + 3.0 * (patch % 8.0),
                p[1] + 3.0 * (patch / 8.0).floor(),
            ]
        })
        .collect()
}

#[allow(dead_code)] // the callgrind driver and the OpenSubdiv bench only (each bench uses some cages)
pub fn triangle_fan(valence: usize) -> (Cage, Vec<f32>) {
    let mut points = vec![0.0f32, 0.0, 0.0];
    let mut indices = Vec::with_capacity(3 * valence);
    for i in 0..valence {
        let a = 2.0 * std::f64::consts::PI * i as f64 / valence as f64;
        points.extend([a.cos() as f32, a.sin() as f32, 0.0]);
        indices.extend([0, 1 + i as i64, 1 + ((i + 1) % valence) as i64]);
    }
    let cage = Cage::from_indices(valence + 1, &vec![3; valence], &indices).expect("a fan");
    (cage, points)
}

/// A single `k`-gon on the unit circle.
#[allow(dead_code)] // the callgrind driver and the OpenSubdiv bench only (each bench uses some cages)
pub fn polygon(k: usize) -> (Cage, Vec<f32>) {
    let mut points = Vec::with_capacity(3 * k);
    for i in 0..k {
        let a = 2.0 * std::f64::consts::PI * i as f64 / k as f64;
        points.extend([a.cos() as f32, a.sin() as f32, 0.0]);
    }
    let indices: Vec<i64> = (0..k as i64).collect();
    let cage = Cage::from_indices(k, &[k as i64], &indices).expect("a polygon");
    (cage, points)
}

/// A `n x n` quad grid, bumped, with one crease of `sharpness` along its middle row of edges.
#[allow(dead_code)] // the callgrind driver and the OpenSubdiv bench only (each bench uses some cages)
pub fn creased_grid(n: usize, sharpness: f32) -> (Cage, Vec<f32>) {
    let id = |i: usize, j: usize| (i * (n + 1) + j) as i64;
    let mut points = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            let (x, y) = (i as f32 / n as f32, j as f32 / n as f32);
            points.extend([x, y, 0.1 * ((7.0 * x).sin() + (5.0 * y).cos())]);
        }
    }
    let mut indices = Vec::new();
    for i in 0..n {
        for j in 0..n {
            indices.extend([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    let creases: Vec<(i64, i64, f32)> = (0..n)
        .map(|i| (id(i, n / 2), id(i + 1, n / 2), sharpness))
        .collect();
    let cage = Cage::from_indices((n + 1) * (n + 1), &vec![4; n * n], &indices)
        .and_then(|c| c.with_creases(&creases))
        .expect("a grid");
    (cage, points)
}
