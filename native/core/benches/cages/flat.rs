//! The cage of the adaptive benchmark, shared with the instruction-count driver
//! (`examples/callgrind.rs`).

use bidegree::Cage;

/// A flat n x n grid of quads in z = 0 with a few lifted vertices in one corner (3 x 3 vertices
/// of pseudo-random heights).
pub fn flat_with_detail(n: usize) -> (Cage, Vec<f64>) {
    let id = |a: usize, b: usize| (a * (n + 1) + b) as i64;
    let mut sizes = Vec::new();
    let mut verts = Vec::new();
    for a in 0..n {
        for b in 0..n {
            sizes.push(4);
            verts.extend([id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)]);
        }
    }
    let mut points: Vec<f64> = (0..=n)
        .flat_map(|a| (0..=n).flat_map(move |b| [a as f64, b as f64, 0.0]))
        .collect();
    let heights = [0.9, -0.4, 0.7, 0.3, 1.2, -0.6, 0.5, -0.2, 0.8];
    for (i, h) in heights.iter().enumerate() {
        let v = id(2 + i / 3, 2 + i % 3) as usize;
        points[3 * v + 2] = *h;
    }
    let cage = Cage::from_indices((n + 1) * (n + 1), &sizes, &verts).unwrap();
    (cage, points)
}
