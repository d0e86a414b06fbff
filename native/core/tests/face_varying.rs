//! The indexed form of face-varying output (`Plan::evaluate_face_varying_shared`): expanded per
//! corner it is the per-corner result, bitwise, in every mode; its indices are kept in the
//! plan, every value is used, and seams stay seams.

mod common;

use std::sync::Arc;

use bidegree::{Cage, FaceVaryingMode, Options, OutputKind, Plan, Rules};
use common::{cube, grid, Random, FACE_VARYING_MODES};

/// Per-corner values of `channels` channels that are one value per cage vertex except across
/// `seam` (a predicate on the corner's face), where the face's corners get a shifted copy.
fn seamed_values(cage: &Cage, channels: usize, seam: impl Fn(usize) -> bool) -> Vec<f64> {
    let mut random = Random(7);
    let per_vertex: Vec<f64> = (0..cage.num_vertices() * channels)
        .map(|_| random.next())
        .collect();
    let offsets = cage.face_offsets();
    let mut out = Vec::new();
    for f in 0..cage.num_faces() {
        for &v in &cage.face_vertices()[offsets[f] as usize..offsets[f + 1] as usize] {
            let shift = if seam(f) { 2.0 } else { 0.0 };
            out.extend((0..channels).map(|k| per_vertex[v as usize * channels + k] + shift));
        }
    }
    out
}

/// The cages of the test: the cube with two faces cut off by a seam, a grid with a hole and a
/// semi-sharp crease, and a fan with a triangle and a pentagon.
fn cages() -> Vec<(&'static str, Cage, Vec<f64>)> {
    let (cube, cube_points) = cube();
    let (grid, grid_points) = grid(4, 3);
    let grid = grid
        .with_holes(&[4])
        .unwrap()
        .with_creases(&[(5, 6, 1.5), (6, 7, 1.5)])
        .unwrap();
    let fan = common::cage(7, &[vec![0, 1, 2], vec![0, 2, 3, 4], vec![0, 4, 5, 6, 1]]);
    let fan_points = vec![
        0.0, 0.0, 0.3, 1.0, 0.0, 0.0, 0.7, 0.9, 0.1, -0.4, 1.0, 0.0, -1.0, 0.2, 0.2, -0.6, -0.8,
        0.0, 0.4, -1.0, 0.1,
    ];
    vec![
        ("cube", cube, cube_points),
        ("grid", grid, grid_points),
        ("fan", fan, fan_points),
    ]
}

#[test]
fn the_indexed_form_is_the_per_corner_result() {
    for (name, cage, _) in cages() {
        for (degree, rules) in [
            (2, Rules::Averaging),
            (3, Rules::Averaging),
            (3, Rules::Classic),
            (4, Rules::Averaging),
        ] {
            for output in [OutputKind::Primal, OutputKind::Dual] {
                if rules == Rules::Classic && output == OutputKind::Dual {
                    continue;
                }
                let options = Options {
                    degree,
                    levels: 2,
                    rules,
                    output,
                    ..Options::default()
                };
                let plan = Plan::new(&cage, &options).unwrap();
                for channels in [1, 2, 5] {
                    let values = seamed_values(&cage, channels, |f| f % 3 == 1);
                    for mode in FACE_VARYING_MODES {
                        for limit in [false, true] {
                            if limit && output == OutputKind::Dual {
                                continue;
                            }
                            let what = format!(
                                "{name} degree {degree} {rules:?} {output:?} {channels} channels \
                                 {mode:?} limit {limit}"
                            );
                            let per_corner = plan
                                .evaluate_face_varying(&values, channels, mode, limit)
                                .unwrap();
                            let shared = plan
                                .evaluate_face_varying_shared(&values, channels, None, mode, limit)
                                .unwrap();
                            let count = shared.values.len() / channels;
                            assert_eq!(shared.values.len(), count * channels, "{what}");
                            assert_eq!(shared.indices.len() * channels, per_corner.len(), "{what}");
                            let mut used = vec![false; count];
                            for &i in shared.indices.iter() {
                                used[i as usize] = true;
                            }
                            assert!(used.iter().all(|&u| u), "{what}: a value no corner uses");
                            let expanded = shared.per_corner(channels).unwrap();
                            assert_eq!(expanded, per_corner, "{what}");
                            // The indices are kept: a second call shares them.
                            let again = plan
                                .evaluate_face_varying_shared(&values, channels, None, mode, limit)
                                .unwrap();
                            assert!(Arc::ptr_eq(&again.indices, &shared.indices), "{what}");
                            assert_eq!(again.values, shared.values, "{what}");
                        }
                    }
                }
            }
        }
    }
}

/// Indexed input gives the same result as the same values given per corner, and corners with
/// different indices but equal values stay apart (a seam OpenSubdiv keeps): more values than
/// the weld by value gives.
#[test]
fn indexed_input_keeps_its_seams() {
    let (cage, _) = grid(3, 3);
    let plan = common::plan(&cage, 4, 2);
    // One value per cage vertex (the grid's own coordinates), indexed by vertex...
    let values: Vec<f32> = (0..16)
        .flat_map(|v| [(v % 4) as f32, (v / 4) as f32])
        .collect();
    let by_vertex: Vec<u32> = cage.face_vertices().to_vec();
    // ... and the same values with face 4's corners given their own (equal) values.
    let mut split_values = values.clone();
    let mut split = by_vertex.clone();
    for c in 16..20 {
        split[c] = (split_values.len() / 2) as u32;
        split_values.extend_from_slice(&values[by_vertex[c] as usize * 2..][..2]);
    }
    for mode in FACE_VARYING_MODES {
        let welded = plan
            .evaluate_face_varying_shared(&values, 2, Some(&by_vertex), mode, false)
            .unwrap();
        let per_corner: Vec<f32> = by_vertex
            .iter()
            .flat_map(|&i| values[i as usize * 2..][..2].to_vec())
            .collect();
        let same = plan
            .evaluate_face_varying_shared(&per_corner, 2, None, mode, false)
            .unwrap();
        assert_eq!(welded, same, "{mode:?}");
        let apart = plan
            .evaluate_face_varying_shared(&split_values, 2, Some(&split), mode, false)
            .unwrap();
        assert_eq!(apart.indices.len(), plan.output_face_vertices().len());
        assert!(
            apart.values.len() > welded.values.len(),
            "{mode:?}: the seam around face 4 has values of its own"
        );
        let expanded = apart.per_corner(2).unwrap();
        let expected = plan
            .evaluate_face_varying_indexed(&split_values, 2, &split, mode, false)
            .unwrap();
        assert_eq!(expanded, expected, "{mode:?}");
    }
}

/// Bad input is refused with a typed error, as the per-corner call refuses it.
#[test]
fn the_indexed_form_refuses_what_the_per_corner_call_refuses() {
    let (cage, _) = cube();
    let plan = common::plan(&cage, 3, 1);
    let corners = cage.face_vertices().len();
    let too_few = vec![0.0f64; 2 * corners - 2];
    assert!(plan
        .evaluate_face_varying_shared(&too_few, 2, None, FaceVaryingMode::None, false)
        .is_err());
    let values = vec![0.5f64; 2 * 3];
    let out_of_range = vec![3u32; corners];
    assert!(plan
        .evaluate_face_varying_shared(
            &values,
            2,
            Some(&out_of_range),
            FaceVaryingMode::None,
            false
        )
        .is_err());
    let mut nan = vec![0.25f64; 2 * corners];
    nan[5] = f64::NAN;
    assert!(plan
        .evaluate_face_varying_shared(&nan, 2, None, FaceVaryingMode::Boundaries, false)
        .is_err());
    let dual = Plan::new(
        &cage,
        &Options {
            degree: 4,
            levels: 1,
            output: OutputKind::Dual,
            ..Options::default()
        },
    )
    .unwrap();
    assert!(dual
        .evaluate_face_varying_shared(
            &vec![0.5f64; 2 * corners],
            2,
            None,
            FaceVaryingMode::None,
            true
        )
        .is_err());
}
