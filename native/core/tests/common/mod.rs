//! Cages shared by the integration tests.
#![allow(dead_code)]

use bidegree::{Cage, FaceVaryingMode, Options, Plan};

/// Every face-varying interpolation mode, in OpenSubdiv's order.
pub const FACE_VARYING_MODES: [FaceVaryingMode; 6] = [
    FaceVaryingMode::None,
    FaceVaryingMode::CornersOnly,
    FaceVaryingMode::CornersPlus1,
    FaceVaryingMode::CornersPlus2,
    FaceVaryingMode::Boundaries,
    FaceVaryingMode::All,
];

/// A deterministic pseudo-random stream in [0, 1) (splitmix64).
pub struct Random(pub u64);

impl Random {
    pub fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Converts face lists to the cage's flat arrays.
pub fn cage(num_vertices: usize, faces: &[Vec<usize>]) -> Cage {
    let sizes: Vec<i64> = faces.iter().map(|f| f.len() as i64).collect();
    let verts: Vec<i64> = faces.iter().flatten().map(|&v| v as i64).collect();
    Cage::from_indices(num_vertices, &sizes, &verts).unwrap()
}

/// An m x n quad grid closed in both directions (a torus), vertex (a, b) = a * n + b.
pub fn torus(m: usize, n: usize) -> Cage {
    let id = |a: usize, b: usize| (a % m) * n + (b % n);
    let faces: Vec<Vec<usize>> = (0..m)
        .flat_map(|a| {
            (0..n).map(move |b| vec![id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)])
        })
        .collect();
    cage(m * n, &faces)
}

/// An open (m+1) x (n+1) vertex grid of quads in the plane z = 0, with its points.
pub fn grid(m: usize, n: usize) -> (Cage, Vec<f64>) {
    let id = |a: usize, b: usize| a * (n + 1) + b;
    let faces: Vec<Vec<usize>> = (0..m)
        .flat_map(|a| {
            (0..n).map(move |b| vec![id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)])
        })
        .collect();
    let points = (0..=m)
        .flat_map(|a| (0..=n).flat_map(move |b| [a as f64, b as f64, 0.0]))
        .collect();
    (cage((m + 1) * (n + 1), &faces), points)
}

/// A planar disk of `rings` rings of quads around one vertex of valence `k` (vertex 0): sector s
/// is a rings x rings grid spanned by directions s and s+1; sector s's v-axis is sector s+1's
/// u-axis. Returns the cage and its points.
pub fn polar_grid(k: usize, rings: usize) -> (Cage, Vec<f64>) {
    // Vertex (s, i, j), i in 1..=rings, j in 0..=rings (j = 0 the u-axis), plus the centre.
    let id = |s: usize, i: usize, j: usize| -> usize {
        if i == 0 && j == 0 {
            0
        } else if i == 0 {
            // On sector s's v-axis: sector s+1's u-axis.
            1 + ((s + 1) % k) * rings * (rings + 1) + (j - 1) * (rings + 1)
        } else {
            1 + s * rings * (rings + 1) + (i - 1) * (rings + 1) + j
        }
    };
    let mut faces = Vec::new();
    for s in 0..k {
        for i in 0..rings {
            for j in 0..rings {
                faces.push(vec![
                    id(s, i, j),
                    id(s, i + 1, j),
                    id(s, i + 1, j + 1),
                    id(s, i, j + 1),
                ]);
            }
        }
    }
    let n = 1 + k * rings * (rings + 1);
    let mut points = vec![0.0; 3 * n];
    for s in 0..k {
        let angle = |t: usize| 2.0 * std::f64::consts::PI * t as f64 / k as f64;
        let (u, v) = (
            (angle(s).cos(), angle(s).sin()),
            (angle(s + 1).cos(), angle(s + 1).sin()),
        );
        for i in 1..=rings {
            for j in 0..=rings {
                let p = id(s, i, j);
                points[3 * p] = i as f64 * u.0 + j as f64 * v.0;
                points[3 * p + 1] = i as f64 * u.1 + j as f64 * v.1;
            }
        }
    }
    (cage(n, &faces), points)
}

/// The cube [-1, 1]^3 with outward faces, and its points.
pub fn cube() -> (Cage, Vec<f64>) {
    let faces = vec![
        vec![0, 3, 2, 1],
        vec![4, 5, 6, 7],
        vec![0, 1, 5, 4],
        vec![1, 2, 6, 5],
        vec![2, 3, 7, 6],
        vec![3, 0, 4, 7],
    ];
    let points = vec![
        -1., -1., -1., 1., -1., -1., 1., 1., -1., -1., 1., -1., -1., -1., 1., 1., -1., 1., 1., 1.,
        1., -1., 1., 1.,
    ];
    (cage(8, &faces), points)
}

/// A plan with the given degree and levels and default options otherwise.
pub fn plan(cage: &Cage, degree: u32, levels: u32) -> Plan {
    Plan::new(
        cage,
        &Options {
            degree,
            levels,
            ..Options::default()
        },
    )
    .unwrap()
}
