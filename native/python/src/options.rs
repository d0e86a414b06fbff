//! Option strings and numbers from Python into the core's option types, and back.

use bidegree::{
    Boundary, Creasing, Error, FaceVaryingMode, NormalDomain, Options, OutputKind, Rules,
    MAX_DEGREE, MAX_LEVELS,
};

use crate::errors::invalid;

/// `"primal"` or `"dual"`.
pub(crate) fn parse_output(output: &str) -> bidegree::Result<OutputKind> {
    match output {
        "primal" => Ok(OutputKind::Primal),
        "dual" => Ok(OutputKind::Dual),
        other => Err(invalid(format!(
            "output must be 'primal' or 'dual', not {other:?}"
        ))),
    }
}

/// `"edge-only"`, `"edge-and-corner"` or `"none"`.
pub(crate) fn parse_boundary(boundary: &str) -> bidegree::Result<Boundary> {
    match boundary {
        "edge-only" => Ok(Boundary::EdgeOnly),
        "edge-and-corner" => Ok(Boundary::EdgeAndCorner),
        "none" => Ok(Boundary::None),
        other => Err(invalid(format!(
            "boundary must be 'edge-only', 'edge-and-corner' or 'none', not {other:?}"
        ))),
    }
}

/// One of OpenSubdiv's face-varying modes: `"none"`, `"corners-only"`, `"corners-plus1"`,
/// `"corners-plus2"`, `"boundaries"`, `"all"`.
pub(crate) fn parse_face_varying_mode(mode: &str) -> bidegree::Result<FaceVaryingMode> {
    Ok(match mode {
        "none" => FaceVaryingMode::None,
        "corners-only" => FaceVaryingMode::CornersOnly,
        "corners-plus1" => FaceVaryingMode::CornersPlus1,
        "corners-plus2" => FaceVaryingMode::CornersPlus2,
        "boundaries" => FaceVaryingMode::Boundaries,
        "all" => FaceVaryingMode::All,
        other => {
            return Err(invalid(format!(
                "uv_mode must be 'none', 'corners-only', 'corners-plus1', 'corners-plus2', \
                 'boundaries' or 'all', not {other:?}"
            )))
        }
    })
}

/// The normals' domain from its Python name (`"corner"` or `"vertex"`).
pub(crate) fn parse_normal_domain(domain: &str) -> bidegree::Result<NormalDomain> {
    match domain {
        "corner" => Ok(NormalDomain::Corner),
        "vertex" => Ok(NormalDomain::Vertex),
        other => Err(invalid(format!(
            "normals must be 'corner' or 'vertex', not {other:?}"
        ))),
    }
}

/// The Python name of an output kind.
pub(crate) fn output_name(output: OutputKind) -> &'static str {
    match output {
        OutputKind::Primal => "primal",
        OutputKind::Dual => "dual",
    }
}

/// `"averaging"` or `"classic"`, and `"uniform"` or `"chaikin"`.
pub(crate) fn parse_rules(rules: &str, creasing: &str) -> bidegree::Result<(Rules, Creasing)> {
    let rules = match rules {
        "averaging" => Rules::Averaging,
        "classic" => Rules::Classic,
        other => {
            return Err(Error::InvalidInput(format!(
                "rules must be 'averaging' or 'classic', not {other:?}"
            )))
        }
    };
    let creasing = match creasing {
        "uniform" => Creasing::Uniform,
        "chaikin" => Creasing::Chaikin,
        other => {
            return Err(Error::InvalidInput(format!(
                "creasing must be 'uniform' or 'chaikin', not {other:?}"
            )))
        }
    };
    Ok((rules, creasing))
}

/// The Python name of a boundary rule.
pub(crate) fn boundary_name(boundary: Boundary) -> &'static str {
    match boundary {
        Boundary::EdgeOnly => "edge-only",
        Boundary::EdgeAndCorner => "edge-and-corner",
        Boundary::None => "none",
    }
}

/// The Python name of a rule set.
pub(crate) fn rules_name(rules: Rules) -> &'static str {
    match rules {
        Rules::Averaging => "averaging",
        Rules::Classic => "classic",
    }
}

/// The Python name of a creasing method.
pub(crate) fn creasing_name(creasing: Creasing) -> &'static str {
    match creasing {
        Creasing::Uniform => "uniform",
        Creasing::Chaikin => "chaikin",
    }
}

/// A degree from Python (`i64`, so that a negative or huge value is reported as the range error
/// it is; the core checks the range itself).
pub(crate) fn degree(degree: i64) -> bidegree::Result<u32> {
    u32::try_from(degree).map_err(|_| Error::DegreeOutOfRange {
        degree,
        max: MAX_DEGREE,
    })
}

/// A number of levels from Python (as [`degree`]).
pub(crate) fn levels(levels: i64) -> bidegree::Result<u32> {
    u32::try_from(levels).map_err(|_| Error::LevelOutOfRange {
        levels,
        min: 0,
        max: MAX_LEVELS,
    })
}

/// A memory budget from Python: `None` is the default budget (4 GiB, or the machine's memory
/// when less).
pub(crate) fn memory_budget(budget: Option<u64>) -> u64 {
    budget.unwrap_or_else(bidegree::memory::default_memory_budget)
}

/// Options from Python arguments.
pub(crate) fn options(
    degree: i64,
    levels: i64,
    output: &str,
    boundary: &str,
    budget: Option<u64>,
    rules: &str,
    creasing: &str,
) -> bidegree::Result<Options> {
    let (rules, creasing) = parse_rules(rules, creasing)?;
    Ok(Options {
        degree: self::degree(degree)?,
        levels: self::levels(levels)?,
        output: parse_output(output)?,
        boundary: parse_boundary(boundary)?,
        memory_budget: memory_budget(budget),
        rules,
        creasing,
    })
}
