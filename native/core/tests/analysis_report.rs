//! The analysis of §4 computed from the engine: the Fourier blocks against the full matrix, the
//! Doo-Sabin spectrum against the discrete Fourier transform of Eq. 1's weights, and the C1 checks
//! (spectrum, characteristic map Jacobian and winding number) for degrees 2..9.

use bidegree::analysis::{subdivision_matrix, C64};
use std::f64::consts::PI;

/// The Doo-Sabin weight of Eq. 1 at offset `d` on a k-gon.
fn w(k: usize, d: usize) -> f64 {
    let d = d % k;
    1.0 / (4.0 * k as f64)
        + if d == 0 { 0.5 } else { 0.0 }
        + if d == 1 || d == k - 1 { 0.125 } else { 0.0 }
}

/// The degree-2 matrix maps the k-gon's faces `(s, 0, 0)` to themselves by Eq. 1 (a circulant),
/// so its spectrum is that circulant's, `sum_d w_d w^(d m)` = 1 for `m = 0` and
/// `1/2 + cos(2 pi m / k) / 4` otherwise, together with the spectrum of the rest of the matrix
/// (the faces off the k-gon, which the k-gon does not see). The k-gon part is the minimal invariant
/// neighbourhood (N = 1) and holds the leading eigenvalues; it is tested exactly, per Fourier mode.
#[test]
fn doo_sabin_spectrum_is_the_fourier_transform_of_its_weights() {
    for k in 3..=16 {
        let m = subdivision_matrix(2, k).unwrap();
        assert!(m.symmetry_defect() < 1e-15, "k {k}");
        let kgon: Vec<usize> = (0..m.labels.len())
            .filter(|&r| m.labels[r].1 == 0 && m.labels[r].2 == 0)
            .collect();
        assert_eq!(kgon.len(), k);
        // Rows of the k-gon: Eq. 1 on the k-gon, nothing elsewhere.
        for &r in &kgon {
            for c in 0..m.labels.len() {
                let (s, t) = (m.labels[r].0, m.labels[c].0);
                let expected = if kgon.contains(&c) {
                    w(k, t + k - s)
                } else {
                    0.0
                };
                assert!(
                    (m.matrix[(r, c)] - expected).abs() < 1e-15,
                    "k {k}: row {:?} column {:?}",
                    m.labels[r],
                    m.labels[c]
                );
            }
        }
        let blocks = m.fourier_blocks();
        let spectra = m.block_eigenvalues().unwrap();
        let rest_max = (0..k)
            .flat_map(|mode| {
                let b = &blocks[mode];
                let a = b.labels.iter().position(|&l| l == (0, 0, 0)).unwrap();
                // The k-gon item is invariant in every block: its row vanishes off the diagonal.
                for c in 0..b.matrix.ncols() {
                    if c != a {
                        assert!(b.matrix[(a, c)].norm() < 1e-14);
                    }
                }
                let dft: C64 = (0..k)
                    .map(|d| C64::from_polar(w(k, d), 2.0 * PI * (d * mode) as f64 / k as f64))
                    .sum();
                let expected = if mode == 0 {
                    1.0
                } else {
                    0.5 + 0.25 * (2.0 * PI * mode as f64 / k as f64).cos()
                };
                assert!((dft - expected).norm() < 1e-14);
                assert!((b.matrix[(a, a)] - dft).norm() < 1e-14, "k {k} mode {mode}");
                // The block's spectrum holds the DFT value: the leading one.
                let values = &spectra[mode];
                assert!(
                    (values[0] - dft).norm() < 1e-12,
                    "k {k} mode {mode}: {} vs {dft}",
                    values[0]
                );
                values[1..].iter().map(|z| z.norm()).collect::<Vec<_>>()
            })
            .fold(0.0, f64::max);
        // The rest of the spectrum lies below every k-gon eigenvalue but can tie the smallest
        // one (1/4 at m = k/2): the rest is the regular part, at most 1/4.
        assert!(rest_max < 0.25 + 1e-9, "k {k}: rest {rest_max}");
        // The leading eigenvalues of the whole matrix, sorted, are the circulant's.
        let mut dft: Vec<f64> = (0..k)
            .map(|mode| {
                if mode == 0 {
                    1.0
                } else {
                    0.5 + 0.25 * (2.0 * PI * mode as f64 / k as f64).cos()
                }
            })
            .collect();
        dft.sort_by(|a, b| b.total_cmp(a));
        let all = m.eigenvalues_by_blocks().unwrap();
        for (i, e) in dft.iter().enumerate().filter(|(_, &e)| e > 0.25 + 1e-6) {
            assert!((all[i].0 - e).norm() < 1e-12, "k {k}: eigenvalue {i}");
        }
    }
}

/// The union of the Fourier blocks' spectra is the full matrix's spectrum (the eigenvalues of
/// visible size: the nilpotent part's zeros are only known to the deflation threshold's root).
#[test]
fn block_eigenvalues_equal_the_full_matrix_eigenvalues() {
    for (degree, k) in [
        (2, 5),
        (3, 3),
        (3, 7),
        (4, 5),
        (4, 8),
        (5, 6),
        (6, 3),
        (7, 5),
    ] {
        let m = subdivision_matrix(degree, k).unwrap();
        assert!(m.symmetry_defect() < 1e-14, "degree {degree} k {k}");
        let blocks = m.eigenvalues_by_blocks().unwrap();
        let full = m.eigenvalues().unwrap();
        assert_eq!(blocks.len(), full.len());
        let mut used = vec![false; full.len()];
        for (z, mode) in blocks.iter().filter(|(z, _)| z.norm() > 1e-2) {
            let best = (0..full.len())
                .filter(|&i| !used[i])
                .min_by(|&a, &b| {
                    let da = (C64::new(full[a].0, full[a].1) - z).norm();
                    let db = (C64::new(full[b].0, full[b].1) - z).norm();
                    da.total_cmp(&db)
                })
                .unwrap();
            used[best] = true;
            let gap = (C64::new(full[best].0, full[best].1) - z).norm();
            assert!(
                gap < 1e-7,
                "degree {degree} k {k}: block {mode} eigenvalue {z} vs full {:?}",
                full[best]
            );
        }
        // The full matrix has no sizeable eigenvalue the blocks missed.
        for (i, f) in full.iter().enumerate() {
            if !used[i] {
                assert!(
                    f.0.hypot(f.1) < 2e-2,
                    "degree {degree} k {k}: {f:?} unmatched"
                );
            }
        }
        // Modes m and k - m are complex conjugate.
        let spectra = m.block_eigenvalues().unwrap();
        for mode in 1..k {
            let (a, b) = (&spectra[mode], &spectra[k - mode]);
            assert!((a[0] - b[0].conj()).norm() < 1e-9);
        }
    }
}

/// The paper's §4 result, checked numerically: degrees 2 through 9 are C1 at irregular points,
/// and (for valences above 4) the third eigenvalue exceeds the square of the subdominant one, so
/// they are not C2.
#[test]
fn degrees_two_to_nine_are_c1() {
    let started = std::time::Instant::now();
    let mut table = String::new();
    for degree in 2..=9 {
        for k in 3..=16 {
            let m = subdivision_matrix(degree, k).unwrap();
            let r = m.report(4).unwrap();
            assert!(r.c1, "degree {degree} k {k}:\n{r}");
            assert_eq!(r.winding, 1, "degree {degree} k {k}");
            assert!(r.jacobian_min > 0.0, "degree {degree} k {k}");
            // The third eigenvalue comes from modes 2 and k - 2 (the paper's B(cos(4 pi / k))).
            if k > 4 {
                assert!(
                    r.third_mode == 2 || r.third_mode == k - 2,
                    "degree {degree} k {k}:\n{r}"
                );
            }
            if k > 4 && degree >= 3 {
                assert!(r.c2_excluded, "degree {degree} k {k}:\n{r}");
            }
            if k == 4 {
                assert!((r.subdominant[0].re - 0.5).abs() < 1e-12);
                assert!(!r.c2_excluded);
            }
            table.push_str(&format!(
                "{degree} {k:2} {:.6} {:.6} {:.4} {:.4}\n",
                r.subdominant[0].re,
                r.third.norm(),
                r.jacobian_min,
                r.jacobian_max
            ));
        }
    }
    println!("degree valence lambda1 |lambda3| J_min J_max\n{table}");
    println!("took {:?}", started.elapsed());
}

/// The refined net is the characteristic map: one more engine step scales it by `lambda1`
/// (`Phi(y / 2) = lambda1 Phi(y)`: the same grid index one level finer is half the parameter).
#[test]
fn the_characteristic_map_scales_by_the_subdominant_eigenvalue() {
    use bidegree::analysis::characteristic_map;
    for (degree, k) in [(2, 7), (3, 5), (4, 3), (7, 9)] {
        let coarse = characteristic_map(degree, k, 3).unwrap();
        let fine = characteristic_map(degree, k, 4).unwrap();
        let lambda = coarse.lambda;
        assert!((fine.lambda - lambda).abs() < 1e-14);
        let mut worst: f64 = 0.0;
        for s in 0..k {
            for r in 0..coarse.rows {
                for c in 0..coarse.columns {
                    let a = coarse.points[s][r * coarse.columns + c];
                    let b = fine.points[s][r * fine.columns + c];
                    worst = worst.max((b[0] - lambda * a[0]).hypot(b[1] - lambda * a[1]));
                }
            }
        }
        assert!(worst < 1e-12, "degree {degree} k {k}: {worst}");
        // Normalised: the first level-1 point at distance one.
        assert!(coarse.jacobian_min > 0.0 && coarse.winding == 1);
    }
}

/// Larger valences (about 35 s in release mode, so not run by default:
/// `cargo test --release --test analysis_report -- --ignored`).
#[test]
#[ignore]
fn degrees_two_to_nine_are_c1_at_large_valences() {
    for k in [20, 30, 40] {
        for degree in 2..=9 {
            let r = subdivision_matrix(degree, k).unwrap().report(4).unwrap();
            assert!(r.c1 && r.c2_excluded, "degree {degree} k {k}:\n{r}");
        }
    }
}
