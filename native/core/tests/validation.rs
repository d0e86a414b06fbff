//! Every refusal is a typed error naming the offending item, raised before any work.

mod common;

use bidegree::{subdivide, Cage, Error, Options, OutputKind, Plan};
use common::{cage, grid, torus};

fn err(r: Result<impl std::fmt::Debug, Error>) -> Error {
    r.expect_err("should be refused")
}

#[test]
fn topology_errors_name_the_offender() {
    assert!(matches!(
        err(Cage::from_indices(3, &[], &[])),
        Error::EmptyMesh(_)
    ));
    assert!(matches!(
        err(Cage::from_indices(0, &[3], &[0, 1, 2])),
        Error::EmptyMesh(_)
    ));
    assert_eq!(
        err(Cage::from_indices(4, &[3, 2], &[0, 1, 2, 2, 3])),
        Error::FaceTooSmall { face: 1, size: 2 }
    );
    assert_eq!(
        err(Cage::from_indices(4, &[3, 3], &[0, 1, 2, 2, 3, 2])),
        Error::RepeatedVertex { face: 1, vertex: 2 }
    );
    // A vertex may come back in a later face, not in its own: also in a very large polygon,
    // whose check is linear in its size.
    let n = 200_000;
    let big: Vec<i64> = (0..n).collect();
    let big_cage = Cage::from_indices(n as usize, &[n], &big).unwrap();
    assert_eq!(big_cage.num_faces(), 1);
    let mut repeated = big.clone();
    repeated[n as usize - 1] = 7;
    assert_eq!(
        err(Cage::from_indices(
            n as usize,
            &[3, n],
            &[7, 8, 9]
                .iter()
                .copied()
                .chain(repeated)
                .collect::<Vec<_>>()
        )),
        Error::RepeatedVertex { face: 1, vertex: 7 }
    );
    assert!(matches!(
        err(Cage::from_indices(3, &[3], &[0, 1, 3])),
        Error::IndexOutOfRange { index: 3, .. }
    ));
    assert!(matches!(
        err(Cage::from_indices(3, &[3], &[0, -1, 2])),
        Error::IndexOutOfRange { index: -1, .. }
    ));
    assert!(matches!(
        err(Cage::from_indices(3, &[3], &[0, 1])),
        Error::InvalidInput(_)
    ));

    // Three triangles on edge (0, 1).
    let fan = cage(5, &[vec![0, 1, 2], vec![1, 0, 3], vec![0, 1, 4]]);
    let e = err(Plan::new(&fan, &Options::default()));
    assert!(
        matches!(e, Error::NonManifoldEdge { faces: 3, .. }),
        "{e:?}"
    );
    // Two triangles traversing (0, 1) the same way.
    let flipped = cage(4, &[vec![0, 1, 2], vec![0, 1, 3]]);
    let e = err(Plan::new(&flipped, &Options::default()));
    assert!(
        matches!(
            e,
            Error::InconsistentOrientation {
                face_a: 0,
                face_b: 1,
                ..
            }
        ),
        "{e:?}"
    );
    // A crease on a vertex pair that is no edge.
    let (g, _) = grid(2, 2);
    let e = err(Plan::new(
        &g.clone().with_creases(&[(0, 8, 1.0)]).unwrap(),
        &Options::default(),
    ));
    assert_eq!(
        e,
        Error::CreaseNotAnEdge {
            crease: 0,
            a: 0,
            b: 8
        }
    );
    assert!(matches!(
        err(g.clone().with_creases(&[(0, 1, -1.0)])),
        Error::InvalidInput(_)
    ));
    assert!(matches!(
        err(g.clone().with_corners(&[(99, 1.0)])),
        Error::IndexOutOfRange { index: 99, .. }
    ));
}

#[test]
fn option_and_budget_errors() {
    let t = torus(4, 4);
    for degree in [0, 32] {
        let e = err(Plan::new(
            &t,
            &Options {
                degree,
                ..Options::default()
            },
        ));
        assert_eq!(
            e,
            Error::DegreeOutOfRange {
                degree: degree as i64,
                max: 31
            }
        );
    }
    assert!(matches!(
        err(Plan::new(
            &t,
            &Options {
                levels: 17,
                ..Options::default()
            }
        )),
        Error::LevelOutOfRange { levels: 17, .. }
    ));
    let e = err(Plan::new(
        &t,
        &Options {
            levels: 12,
            ..Options::default()
        },
    ));
    assert!(matches!(e, Error::MemoryBudget { .. }), "{e:?}");
    let e = err(Plan::new(
        &t,
        &Options {
            levels: 3,
            memory_budget: 1000,
            ..Options::default()
        },
    ));
    assert!(
        matches!(e, Error::MemoryBudget { budget: 1000, .. }),
        "{e:?}"
    );
}

#[test]
fn geometry_errors() {
    let (g, mut points) = grid(2, 2);
    points[3 * 4 + 1] = f64::NAN;
    assert_eq!(
        err(subdivide(&g, &points, 3, &Options::default())),
        Error::NonFinite { vertex: 4 }
    );
    let (g, points) = grid(2, 2);
    assert!(matches!(
        err(subdivide(&g, &points[..9], 3, &Options::default())),
        Error::InvalidInput(_)
    ));
    // Collapse face 3 (vertices 4, 7, 8, 5) onto a line.
    let mut flat = points.clone();
    for v in [7, 8] {
        flat[3 * v] = flat[3 * 4];
        flat[3 * v + 1] = flat[3 * 4 + 1];
    }
    flat[3 * 5] = flat[3 * 4];
    assert_eq!(
        err(subdivide(&g, &flat, 3, &Options::default())),
        Error::DegenerateFace { face: 3 }
    );
    // A plan evaluates any finite pose, but still refuses NaN.
    let plan = Plan::new(&g, &Options::default()).unwrap();
    assert!(plan.evaluate(&flat, 3).is_ok());
    let mut nan = points.clone();
    nan[0] = f64::INFINITY;
    assert_eq!(err(plan.evaluate(&nan, 3)), Error::NonFinite { vertex: 0 });
}

#[test]
fn isolated_vertices_are_dropped() {
    // Vertex 2 is used by no face.
    let c = cage(5, &[vec![0, 1, 3], vec![3, 1, 4]]);
    let plan = Plan::new(
        &c,
        &Options {
            degree: 3,
            levels: 1,
            ..Options::default()
        },
    )
    .unwrap();
    assert_eq!(plan.isolated_vertices(), &[2]);
    let points = [0., 0., 0., 1., 0., 0., 9., 9., 9., 0., 1., 0., 1., 1., 0.];
    let out = plan.evaluate(&points, 3).unwrap();
    assert_eq!(out.len(), 3 * plan.num_output_vertices());
    assert!(
        out.iter().all(|&x| x < 5.0),
        "the isolated vertex must not leak into the result"
    );
}

#[test]
fn dual_output_refuses_valence_two_vertices() {
    let c = cage(3, &[vec![0, 1, 2], vec![2, 1, 0]]);
    let e = err(Plan::new(
        &c,
        &Options {
            output: OutputKind::Dual,
            levels: 1,
            ..Options::default()
        },
    ));
    assert!(matches!(e, Error::InvalidInput(_)), "{e:?}");
}

/// Issue 18 item 9: a negative face size is said as given, and a level range names its lower
/// bound (adaptive subdivision refines at least one level).
#[test]
fn sizes_and_levels_are_said_as_given() {
    let e = err(Cage::from_indices(4, &[-4], &[0, 1, 2, 3]));
    assert_eq!(e, Error::FaceTooSmall { face: 0, size: -4 });
    assert_eq!(
        e.to_string(),
        "face 0 has size -4; faces need at least 3 vertices"
    );
    let e = err(Plan::new(
        &torus(4, 4),
        &Options {
            levels: 17,
            ..Options::default()
        },
    ));
    assert_eq!(e.to_string(), "levels 17 is out of range 0..=16");
    let adaptive = bidegree::AdaptiveOptions {
        max_level: 0,
        ..bidegree::AdaptiveOptions::default()
    };
    let (g, points) = grid(3, 3);
    let e = err(bidegree::subdivide_adaptive(&g, &points, &adaptive));
    assert_eq!(e.to_string(), "levels 0 is out of range 1..=16");
}

/// Issue 18 item 4: a budget raised above the machine's memory does not let a request in that
/// the machine cannot hold; it is refused from the estimate, before any work.
#[test]
fn a_budget_above_the_machine_is_refused_before_any_work() {
    let Some(machine) = bidegree::memory::machine_memory() else {
        return; // not known on this system: the budget alone holds
    };
    let options = Options {
        levels: 14,
        memory_budget: u64::MAX,
        ..Options::default()
    };
    match err(Plan::new(&torus(8, 8), &options)) {
        Error::OutOfMemory {
            required,
            available,
        } => assert!(available == machine && required > machine),
        e => panic!("{e:?}"),
    }
    assert!(Options::default().memory_budget <= machine);
}
