//! Arbitrary input never panics: any polygon soup, crease list, degree and level count either
//! subdivides or is refused with a typed error.

use bidegree::{
    subdivide, subdivide_adaptive, AdaptiveOptions, Boundary, Cage, Options, OutputKind, Plan,
    Rules,
};
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

/// A corner on a vertex that no face uses has no place in the surface: it is left out, and the
/// result is the one without it, for every degree and rule set, both outputs, the limits and
/// adaptive subdivision (it used to panic with an index out of bounds, issue 18).
#[test]
fn a_corner_on_an_isolated_vertex_is_left_out() {
    let points = [0.0, 0.0, 0.0, 1.0, 0.0, 0.2, 0.0, 1.0, 0.4, 5.0, 5.0, 5.0];
    let plain = Cage::from_indices(4, &[3], &[0, 1, 2]).unwrap();
    let cornered = plain.clone().with_corners(&[(3, 2.0)]).unwrap();
    let schemes = (1..=9)
        .map(|d| (d, Rules::Averaging))
        .chain((1..=3).map(|d| (d, Rules::Classic)));
    for (degree, rules) in schemes {
        for output in [OutputKind::Primal, OutputKind::Dual] {
            for levels in 0..=2 {
                let options = Options {
                    degree,
                    levels,
                    output,
                    rules,
                    ..Options::default()
                };
                let what = format!("degree {degree} {rules:?} {output:?} levels {levels}");
                let (a, b) = (Plan::new(&plain, &options), Plan::new(&cornered, &options));
                let (a, b) = match (a, b) {
                    (Ok(a), Ok(b)) => (a, b),
                    (Err(x), Err(y)) => {
                        assert_eq!(x, y, "{what}");
                        continue;
                    }
                    (a, b) => panic!("{what}: {:?} against {:?}", a.err(), b.err()),
                };
                assert_eq!(b.isolated_vertices(), &[3], "{what}");
                assert_eq!(
                    a.evaluate(&points, 3).unwrap(),
                    b.evaluate(&points, 3).unwrap(),
                    "{what}"
                );
                assert_eq!(
                    a.limit_positions(&points, 3),
                    b.limit_positions(&points, 3),
                    "{what}"
                );
                assert_eq!(a.limit_surface(&points), b.limit_surface(&points), "{what}");
            }
        }
        if rules == Rules::Averaging {
            let options = AdaptiveOptions {
                degree,
                max_level: 2,
                tolerance: 0.0,
                ..AdaptiveOptions::default()
            };
            assert_eq!(
                subdivide_adaptive(&plain, &points, &options).unwrap(),
                subdivide_adaptive(&cornered, &points, &options).unwrap(),
                "adaptive degree {degree}"
            );
        }
    }
}
