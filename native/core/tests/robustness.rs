//! Arbitrary input never panics: any polygon soup, crease list, degree and level count either
//! subdivides or is refused with a typed error.

use bidegree::{subdivide, Boundary, Cage, Options, OutputKind};
use proptest::prelude::*;

type Soup = (usize, Vec<Vec<i64>>, Vec<(i64, i64, f32)>, Vec<f64>);

/// Polygon soups: mostly valid indices and sizes, sometimes not.
fn soup() -> impl Strategy<Value = Soup> {
    (3usize..9).prop_flat_map(|n| {
        let index = prop_oneof![20 => 0i64..n as i64, 1 => -2i64..(n as i64 + 2)];
        let face = (
            prop_oneof![20 => 3usize..6, 1 => 0usize..3],
            prop::collection::vec(index.clone(), 6),
        )
            .prop_map(|(size, indices)| indices[..size].to_vec());
        let faces = prop::collection::vec(face, 1..7);
        let creases = prop::collection::vec((index.clone(), index, 0.0f32..12.0), 0..3);
        let points = prop::collection::vec(-5.0f64..5.0, 3 * n);
        (Just(n), faces, creases, points)
    })
}

/// Valid closed meshes: an m x n torus with random creases and corners.
fn torus() -> impl Strategy<Value = Soup> {
    (3usize..6, 3usize..6).prop_flat_map(|(m, n)| {
        let id = move |a: usize, b: usize| ((a % m) * n + (b % n)) as i64;
        let faces: Vec<Vec<i64>> = (0..m)
            .flat_map(|a| {
                (0..n).map(move |b| vec![id(a, b), id(a + 1, b), id(a + 1, b + 1), id(a, b + 1)])
            })
            .collect();
        let crease = (0..m, 0..n, any::<bool>(), 0.0f32..12.0).prop_map(move |(a, b, down, s)| {
            if down {
                (id(a, b), id(a + 1, b), s)
            } else {
                (id(a, b), id(a, b + 1), s)
            }
        });
        let creases = prop::collection::vec(crease, 0..4);
        let points = prop::collection::vec(-5.0f64..5.0, 3 * m * n);
        (Just(m * n), Just(faces), creases, points)
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    #[test]
    fn arbitrary_input_is_subdivided_or_refused(
        (n, faces, creases, points) in prop_oneof![soup(), torus()],
        degree in 0u32..12,
        levels in 0u32..4,
        dual in any::<bool>(),
        corners in any::<bool>(),
    ) {
        let sizes: Vec<i64> = faces.iter().map(|f| f.len() as i64).collect();
        let indices: Vec<i64> = faces.iter().flatten().copied().collect();
        let options = Options {
            degree,
            levels,
            output: if dual { OutputKind::Dual } else { OutputKind::Primal },
            boundary: if corners { Boundary::EdgeAndCorner } else { Boundary::EdgeOnly },
            ..Options::default()
        };
        let outcome = Cage::from_indices(n, &sizes, &indices)
            .and_then(|cage| cage.with_creases(&creases))
            .and_then(|cage| subdivide(&cage, &points, 3, &options));
        if let Ok((plan, out)) = outcome {
            prop_assert_eq!(out.len(), 3 * plan.num_output_vertices());
            prop_assert!(out.iter().all(|x| x.is_finite()));
            let max = *plan.output_face_vertices().iter().max().unwrap_or(&0) as usize;
            prop_assert!(max < plan.num_output_vertices());
        }
    }
}
