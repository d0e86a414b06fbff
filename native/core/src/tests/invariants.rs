//! Broken structural invariants are `Error::Internal`, not panics: the internal entry points
//! fed what no plan gives them.

use super::common::{grid, plan};
use crate::curves::CurveNetwork;
use crate::step::catmark::step_into;
use crate::topology::NONE;
use crate::{Creasing, Error};

fn is_internal<T>(result: &crate::Result<T>) -> bool {
    matches!(result, Err(Error::Internal(_)))
}

#[test]
fn a_curve_network_that_does_not_continue_the_previous_step_is_an_internal_error() {
    // A grid's boundary is a curve: step 1's curve edges name curve items of step 0's network.
    let (cage, _) = grid(3, 3);
    let plan = plan(&cage, 3, 2);
    let refinement = plan.refinement();
    let (levels, networks) = (refinement.levels_as_built(), refinement.curve_networks());
    let curves = networks[0].next_curves();
    let corners = &refinement.features().corners;
    let build = |previous: &CurveNetwork| {
        CurveNetwork::build(
            &levels[1],
            &curves,
            corners,
            1,
            Some(previous),
            true,
            |_| NONE,
        )
    };
    assert!(build(&networks[0]).is_ok());
    assert!(is_internal(&build(&CurveNetwork::default())));
}

#[test]
fn a_catmull_clark_step_without_sharpness_tables_is_an_internal_error() {
    // The averaging rules' steps carry no sharpness tables.
    let (cage, points) = grid(2, 2);
    let plan = plan(&cage, 3, 1);
    let step = plan.refinement().step(0);
    let values: Vec<[f64; 3]> = points.chunks(3).map(|p| [p[0], p[1], p[2]]).collect();
    let mut out = Vec::new();
    assert!(is_internal(&step_into(
        &step,
        Creasing::Uniform,
        &values,
        &mut out
    )));
}
