//! The engine's subdivision matrices against the paper's §2 and §4: the biquartic stencils of
//! Eq. 2 near an irregular face, and the biquartic block B(c) and its subdominant eigenvalue.

use bidegree::analysis::subdivision_matrix;
use nalgebra::DMatrix;

/// The paper's biquartic block B(c) (§4.2), times 256.
fn paper_block(c: f64) -> DMatrix<f64> {
    let c2 = c * c;
    #[rustfmt::skip]
    let rows = [
        [8.0 * c2 + 58.0 * c + 75.0, 20.0 + 10.0 * c, 1.0, -10.0 + 10.0 * c2, 0.0, 0.0, 0.0, 0.0, 0.0],
        [4.0 * c2 + 54.0 * c + 95.0, 60.0 + 26.0 * c, 5.0, -26.0 + 26.0 * c2, 0.0, 0.0, 0.0, 0.0, 0.0],
        [18.0 * c + 99.0, 100.0 + 10.0 * c, 25.0, -10.0 + 10.0 * c2, 0.0, 0.0, 0.0, 0.0, 0.0],
        [-4.0 * c - 40.0, -24.0, 0.0, -24.0 * c + 40.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [25.0 * c + 50.0, 105.0 + 50.0 * c, 10.0, 50.0 * c2 - 50.0, 5.0 * c + 10.0, 1.0, 0.0, 0.0, -5.0 + 5.0 * c2],
        [5.0 * c + 50.0, 125.0 + 10.0 * c, 50.0, -10.0 + 10.0 * c2, c + 10.0, 5.0, 0.0, 0.0, c2 - 1.0],
        [25.0, 100.0, 100.0, 0.0, 10.0, 20.0, 1.0, 0.0, 0.0],
        [-5.0, -10.0, 0.0, 75.0 - 10.0 * c, -1.0, 0.0, 0.0, 5.0, 10.0 - c],
        [-25.0, -50.0, 0.0, 95.0 - 50.0 * c, -5.0, 0.0, 0.0, 1.0, 10.0 - 5.0 * c],
    ];
    DMatrix::from_fn(9, 9, |r, col| rows[r][col] / 256.0)
}

fn largest_modulus(m: &DMatrix<f64>) -> f64 {
    let schur = nalgebra::linalg::Schur::try_new(m.clone(), 1e-14, 10_000).expect("9x9 converges");
    schur
        .complex_eigenvalues()
        .iter()
        .map(|z| z.norm())
        .fold(0.0, f64::max)
}

#[test]
fn biquartic_subdominant_eigenvalue_matches_the_papers_block() {
    let design = [
        (3, 0.396595),
        (4, 0.5),
        (5, 0.568235),
        (6, 0.612962),
        (8, 0.663926),
    ];
    for k in 3..=12 {
        let m = subdivision_matrix(4, k).unwrap();
        let values = m.eigenvalues().unwrap();
        let modulus = |i: usize| values[i].0.hypot(values[i].1);
        assert!(
            (modulus(0) - 1.0).abs() < 1e-12,
            "k {k}: dominant eigenvalue {:?}",
            values[0]
        );
        assert!(modulus(1) < 1.0 - 1e-6, "k {k}: 1 must be simple");
        let expected = largest_modulus(&paper_block((2.0 * std::f64::consts::PI / k as f64).cos()));
        assert!(
            (modulus(1) - expected).abs() < 1e-9,
            "k {k}: engine {} vs B(c) {expected}",
            modulus(1)
        );
        assert!(
            (modulus(2) - expected).abs() < 1e-9,
            "k {k}: subdominant is double"
        );
        assert!(values[1].1.abs() < 1e-9, "k {k}: subdominant is real");
        if let Some(&(_, value)) = design.iter().find(|d| d.0 == k) {
            assert!(
                (expected - value).abs() < 5e-7,
                "k {k}: {expected} vs DESIGN.md {value}"
            );
        }
    }
}

#[test]
fn valence_four_has_the_tensor_spectrum() {
    for degree in [2, 3, 4, 5] {
        let m = subdivision_matrix(degree, 4).unwrap();
        let values: Vec<f64> = m
            .eigenvalues()
            .unwrap()
            .iter()
            .map(|z| z.0.hypot(z.1))
            .collect();
        let expected = [1.0, 0.5, 0.5, 0.25, 0.25, 0.25];
        for (i, e) in expected.iter().enumerate() {
            assert!(
                (values[i] - e).abs() < 1e-9,
                "degree {degree}: eigenvalue {i} is {} not {e}",
                values[i]
            );
        }
    }
}

/// The Doo-Sabin weight of Eq. 1 at offset `d` on a k-gon.
fn w(k: usize, d: i64) -> f64 {
    let d = d.rem_euclid(k as i64);
    1.0 / (4.0 * k as f64)
        + if d == 0 { 0.5 } else { 0.0 }
        + if d == 1 || d == k as i64 - 1 {
            0.125
        } else {
            0.0
        }
}

#[test]
fn biquartic_stencils_near_an_irregular_face_follow_equation_2() {
    // Children of the dual point p_l (face (l, 0, 0) of the k-gon around the centre): the one at
    // the centre (nw), the two beside it (ne and its mirror image) and the far one (se). Each
    // weight on the k-gon is a fixed part, read off the regular case, plus Eq. 2's addition.
    type Addition = fn(usize, i64) -> f64;
    let nw: Addition =
        |k, d| 64.0 / k as f64 + 48.0 * w(k, d) + 16.0 * w(k, d - 1) + 16.0 * w(k, d + 1);
    let ne: Addition = |k, d| 32.0 * w(k, d) + 16.0 * w(k, d - 1);
    let ne_mirror: Addition = |k, d| 32.0 * w(k, -d) + 16.0 * w(k, -d - 1);
    let se: Addition = |k, d| 16.0 * w(k, d);
    // Children of face (0, 0, 0) at the next level, by grid position: (0,0) touches the centre;
    // (1,0) and (0,1) are beside it; (1,1) is the far one.
    let children: [((usize, usize), Addition); 4] = [
        ((0, 0), nw),
        ((1, 0), ne_mirror),
        ((0, 1), ne),
        ((1, 1), se),
    ];
    let weights = |k: usize, child: (usize, usize), d: i64| -> f64 {
        let m = subdivision_matrix(4, k).unwrap();
        let row = m
            .labels
            .iter()
            .position(|&l| l == (0, child.0, child.1))
            .unwrap();
        let col = m
            .labels
            .iter()
            .position(|&l| l == (d.rem_euclid(k as i64) as usize, 0, 0))
            .unwrap();
        256.0 * m.matrix[(row, col)]
    };
    for (child, addition) in children {
        // Fixed parts on p_l and its neighbours p_{l+1}, p_{l-1} (sector order), from valence 4.
        let fixed: Vec<f64> = [0i64, 1, -1]
            .iter()
            .map(|&d| weights(4, child, d) - addition(4, d))
            .collect();
        for k in 3..=9 {
            for d in 0..k as i64 {
                let near = [0i64, 1, (k - 1) as i64].iter().position(|&x| x == d);
                let expected = near.map_or(0.0, |i| fixed[i]) + addition(k, d);
                let got = weights(k, child, d);
                assert!(
                    (got - expected).abs() < 1e-9,
                    "child {child:?}, k {k}, p_(l+{d}): {got} vs {expected} (x 1/256)"
                );
            }
        }
    }
}

/// `refine`'s extent comes from its caller: one that is not finite, or so large that the
/// polar cage's ring count saturates, is refused as bad input (it panicked: the cage got one
/// ring, and the neighbourhood walk met its boundary).
#[test]
fn refine_refuses_an_extent_it_cannot_hold() {
    use bidegree::analysis::{polar_cage, refine};
    use bidegree::Error;
    let impulse = vec![1.0];
    for extent in [f64::INFINITY, f64::NAN, -1.0] {
        let refused = refine(5, 4, std::slice::from_ref(&impulse), 1, extent);
        assert!(
            matches!(refused, Err(Error::InvalidInput(_))),
            "extent {extent}: {refused:?}"
        );
    }
    let refused = refine(5, 4, &[impulse], 1, 1e30);
    assert!(
        matches!(refused, Err(Error::InvalidInput(_))),
        "{refused:?}"
    );
    let refused = polar_cage(4, usize::MAX / 2);
    assert!(
        matches!(refused, Err(Error::InvalidInput(_))),
        "{:?}",
        refused.map(|_| ())
    );
}
