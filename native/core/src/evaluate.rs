//! Evaluation: running points or any per-vertex attribute through a [`Refinement`], step after
//! step with the step primitive ([`crate::step`]), in buffers kept between evaluations.
//! [`crate::Plan::evaluate`], the limits and face-varying values come through here.

use crate::error::Result;
use crate::memory;
use crate::output::OutputMesh;
use crate::parallel::in_pool;
use crate::refinement::Refinement;
use crate::scalar::{Scalar, Value};
use crate::step::{Final, LevelData, Parts, Scratch, SCRATCH_BUFFERS};

/// Runs `cage` (one value per vertex of `M_0`) through every step of `refinement`, taking and
/// giving back buffers in `scratch`. `want_dual` selects the final kind: the drawing mesh wants
/// primal data, the true dual mesh dual data.
///
/// Every level-sized buffer of the run comes from `scratch`, which is provisioned here first
/// (fallibly: a refusal is [`crate::Error::OutOfMemory`] before any step runs) with the four
/// buffers of the largest level that a windowed step holds; the steps then mostly reuse them
/// (the array a run returns is replaced by the next run's provisioning).
pub(crate) fn run<T: Scalar, const N: usize>(
    refinement: &Refinement,
    scratch: &Scratch,
    cage: &[Value<T, N>],
    want_dual: bool,
) -> Result<Final<T, N>> {
    // The drawing mesh of degrees 2 and 4: the last step ends in its drawing points.
    let drawn = match want_dual {
        true => None,
        false => refinement.drawn_step()?,
    };
    let data = steps(refinement, scratch, cage, drawn.as_ref())?;
    let steps = refinement.curve_networks().len();
    let last = steps.checked_sub(1).map(|j| refinement.step(j));
    Ok(data.finish(last.as_ref(), want_dual))
}

/// As [`run`], leaving the last level's data as the steps make it (per vertex for odd
/// degrees, per face for even ones) with its 1-D data (per curve vertex or curve edge of the
/// last step): what the limit stencils and their local extension read.
pub(crate) fn run_parts<T: Scalar, const N: usize>(
    refinement: &Refinement,
    scratch: &Scratch,
    cage: &[Value<T, N>],
) -> Result<Parts<T, N>> {
    Ok(steps(refinement, scratch, cage, None)?.finish_parts())
}

/// Every step of `refinement` on `cage` (see [`run`]), the last one replaced by `last` when
/// given ([`Refinement::drawn_step`]).
fn steps<'a, T: Scalar, const N: usize>(
    refinement: &Refinement,
    scratch: &'a Scratch,
    cage: &'a [Value<T, N>],
    last: Option<&crate::step::Step>,
) -> Result<LevelData<'a, T, N>> {
    let steps = refinement.curve_networks().len();
    let mut data = LevelData::new(cage);
    if steps > 0 {
        let capacity = scratch_capacity(refinement);
        scratch.provision::<Value<T, N>>(capacity, SCRATCH_BUFFERS)?;
        data = data.with_scratch(scratch, capacity);
    }
    for j in 0..steps {
        match last {
            Some(last) if j + 1 == steps => data.step(last)?,
            _ => data.step(&refinement.step(j))?,
        }
    }
    Ok(data)
}

/// Values a run's buffers hold at most: the largest level's data (and the last step's 1-D
/// points that the dual output appends).
fn scratch_capacity(refinement: &Refinement) -> usize {
    let steps = refinement.curve_networks().len();
    let last = refinement.last_level();
    if steps == 0 || refinement.scheme().uses_sharpness() {
        last.num_vertices
    } else {
        let curve = refinement.curve_networks()[steps - 1].edges().len();
        last.num_vertices.max(last.num_faces() + curve)
    }
}

/// Per-vertex values of the cage (`channels` interleaved values per cage vertex, in the cage's
/// numbering, checked) at the output vertices, interleaved.
pub(crate) fn evaluate<T: Scalar>(
    refinement: &Refinement,
    scratch: &Scratch,
    output: &OutputMesh,
    values: &[T],
    channels: usize,
) -> Result<Vec<T>> {
    let n = |group: &[T], width: usize| match width {
        1 => evaluate_n::<T, 1>(refinement, scratch, output, group),
        2 => evaluate_n::<T, 2>(refinement, scratch, output, group),
        3 => evaluate_n::<T, 3>(refinement, scratch, output, group),
        _ => evaluate_n::<T, 4>(refinement, scratch, output, group),
    };
    in_pool(|| {
        if channels <= 4 {
            n(values, channels)
        } else {
            in_groups_of_four(values, channels, |group| n(&group, 4))
        }
    })
}

fn evaluate_n<T: Scalar, const N: usize>(
    refinement: &Refinement,
    scratch: &Scratch,
    output: &OutputMesh,
    values: &[T],
) -> Result<Vec<T>> {
    let (points, _) = values.as_chunks::<N>();
    let compact = refinement.compact(points);
    let result = run(refinement, scratch, &compact, refinement.wants_dual())?;
    Ok(output.finish(result)?.into_flattened())
}

/// Runs `per_four` (interleaved values of 4 channels in, the same out) on the channels of
/// `values` four at a time (the last group padded with zeros) and interleaves the results back.
pub(crate) fn in_groups_of_four<T: Scalar>(
    values: &[T],
    channels: usize,
    per_four: impl Fn(Vec<T>) -> Result<Vec<T>>,
) -> Result<Vec<T>> {
    let items = values.len() / channels;
    let mut out: Vec<T> = Vec::new();
    for first in (0..channels).step_by(4) {
        let width = (channels - first).min(4);
        let mut group: Vec<T> = memory::with_capacity(4 * items)?;
        group.extend((0..items).flat_map(|i| {
            (0..4).map(move |k| {
                if k < width {
                    values[i * channels + first + k]
                } else {
                    T::default()
                }
            })
        }));
        let result = per_four(group)?;
        let count = result.len() / 4;
        if out.is_empty() {
            out = memory::filled(count * channels, T::default())?;
        }
        for i in 0..count {
            out[i * channels + first..i * channels + first + width]
                .copy_from_slice(&result[4 * i..4 * i + width]);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use crate::{Cage, Options, Plan, Rules};

    /// Kept buffers change nothing: repeated evaluations (f32 and f64, with and without the
    /// buffers of the previous ones) give the same bits.
    #[test]
    fn kept_buffers_do_not_change_results() {
        let points = [
            0.0f64, 0.0, 1.0, -1.0, -1.0, 0.0, 1.0, -1.0, 0.0, 1.0, 1.0, 0.0, -1.0, 1.0, 0.0,
        ];
        let cage =
            Cage::from_indices(5, &[3, 3, 3, 3], &[0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1]).unwrap();
        let classic = (3, Rules::Classic);
        for (degree, rules) in (1..=5).map(|d| (d, Rules::Averaging)).chain([classic]) {
            let options = Options {
                degree,
                levels: 3,
                rules,
                ..Options::default()
            };
            let plan = Plan::new(&cage, &options).unwrap();
            let first = plan.evaluate(&points, 3).unwrap();
            let first32 = plan.evaluate(&points.map(|x| x as f32), 3).unwrap();
            for _ in 0..2 {
                assert_eq!(plan.evaluate(&points, 3).unwrap(), first);
                assert_eq!(
                    plan.evaluate(&points.map(|x| x as f32), 3).unwrap(),
                    first32
                );
            }
            plan.release_buffers();
            assert_eq!(plan.evaluate(&points, 3).unwrap(), first);
        }
    }

    /// The windowed step's partly written buffers keep the values of earlier evaluations
    /// (`LevelData::partial`): the passes read none of them, so evaluating other points in
    /// between changes no bit. A grid with a boundary, a semi-sharp crease and a hole, of quads
    /// (the quad paths from the cage on) and with one quad split into two triangles (two
    /// vertices of valence 5), so that the zone has curves and irregular vertices.
    #[test]
    fn kept_values_of_other_points_do_not_change_results() {
        let side = 6usize;
        let cage = |split: bool| {
            let (mut sizes, mut indices) = (Vec::new(), Vec::new());
            for y in 0..side - 1 {
                for x in 0..side - 1 {
                    let v = (y * side + x) as i64;
                    let s = side as i64;
                    if split && (x, y) == (2, 3) {
                        // Two triangles: two vertices of valence 5 (the cage is not all quads).
                        sizes.extend([3, 3]);
                        indices.extend([v, v + 1, v + s + 1, v, v + s + 1, v + s]);
                    } else {
                        sizes.push(4);
                        indices.extend([v, v + 1, v + s + 1, v + s]);
                    }
                }
            }
            Cage::from_indices(side * side, &sizes, &indices)
                .unwrap()
                .with_creases(&[(14, 15, 1.5), (15, 16, 1.5), (16, 17, 1.5)])
                .unwrap()
                .with_holes(&[12])
                .unwrap()
        };
        let points = |seed: f64| -> Vec<f64> {
            (0..side * side)
                .flat_map(|v| {
                    let (x, y) = ((v % side) as f64, (v / side) as f64);
                    [x, y, (seed * (x + 2.0 * y)).sin()]
                })
                .collect()
        };
        let (a, b) = (points(0.7), points(1.9));
        for (degree, cage) in (3..=9).flat_map(|d| [(d, cage(false)), (d, cage(true))]) {
            let options = Options {
                degree,
                levels: 3,
                ..Options::default()
            };
            let fresh = Plan::new(&cage, &options).unwrap().evaluate(&a, 3).unwrap();
            let plan = Plan::new(&cage, &options).unwrap();
            plan.evaluate(&b, 3).unwrap();
            assert_eq!(plan.evaluate(&a, 3).unwrap(), fresh, "degree {degree}");
            plan.evaluate(&b, 3).unwrap();
            let a32: Vec<f32> = a.iter().map(|&x| x as f32).collect();
            let fresh32 = Plan::new(&cage, &options)
                .unwrap()
                .evaluate(&a32, 3)
                .unwrap();
            let b32: Vec<f32> = b.iter().map(|&x| x as f32).collect();
            plan.evaluate(&b32, 3).unwrap();
            assert_eq!(plan.evaluate(&a32, 3).unwrap(), fresh32, "degree {degree}");
        }
    }

    /// A run of steps allocates no buffer of the level's size beyond the four it provisions
    /// (fallibly): a buffer dropped instead of given back made later steps allocate infallibly
    /// (odd degrees dropped their last step's dual data at every windowed step: a limit of
    /// degree 9 aborted under an address-space limit where it should have been typed).
    #[test]
    fn runs_allocate_only_what_they_provision() {
        use super::run;
        use crate::refinement::Refinement;
        use crate::step::Scratch;
        // A fan of triangles (the first step by the passes), and a grid of quads with a
        // semi-sharp crease, a boundary and a hole (windowed steps, curves).
        let fan = (0..7)
            .flat_map(|i| [0, 1 + i, 1 + (i + 1) % 7])
            .collect::<Vec<i64>>();
        let fan = Cage::from_indices(8, &[3; 7], &fan).unwrap();
        let side = 6i64;
        let grid_faces = (0..side - 1)
            .flat_map(|y| (0..side - 1).map(move |x| y * side + x))
            .flat_map(|v| [v, v + 1, v + side + 1, v + side])
            .collect::<Vec<i64>>();
        let grid = Cage::from_indices(36, &[4; 25], &grid_faces)
            .unwrap()
            .with_creases(&[(12, 13, 2.5), (13, 14, 2.5), (14, 15, 2.5)])
            .unwrap()
            .with_holes(&[7])
            .unwrap();
        let points = |n: usize| -> Vec<[f64; 3]> {
            (0..n)
                .map(|v| [v as f64, (v * v % 7) as f64, (v as f64 * 0.7).sin()])
                .collect()
        };
        let mut schemes: Vec<(u32, Rules)> = (1..=9).map(|d| (d, Rules::Averaging)).collect();
        schemes.extend((1..=3).map(|d| (d, Rules::Classic)));
        for (cage, n) in [(&fan, 8), (&grid, 36)] {
            for &(degree, rules) in &schemes {
                let options = Options {
                    degree,
                    levels: 4,
                    rules,
                    ..Options::default()
                };
                let refinement = Refinement::new(cage, &options).unwrap();
                let cage_points = points(n);
                let compact = refinement.compact(&cage_points);
                let scratch = Scratch::default();
                for want_dual in [false, true, false] {
                    run(&refinement, &scratch, &compact, want_dual).unwrap();
                }
                assert_eq!(scratch.unprovisioned(), 0, "degree {degree} {rules:?}");
            }
        }
    }
}
