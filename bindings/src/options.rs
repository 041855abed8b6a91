//! The encoder options as Python names them, listed once: [`OPTIONS`] gives each option's
//! key, how its value is read from an [`EncoderConfig`] (the defaults that
//! `dynmesh.defaults.ENCODER` and the command line show) and how a value sets it. The
//! command line's flags are these keys with dashes.

use pyo3::prelude::*;
use pyo3::types::PyDict;
use pyo3::IntoPyObjectExt;

use dynmesh::encode::{self, AnchorStages, AqParams, EncoderConfig, LiftingChoice, SchemeChoice, QP_RANGE};

use crate::errors::{core_error, input_error};

/// An encoder configuration being built from options; adaptive quantization's switch and
/// parameters are separate options, so they are kept apart until the end.
struct Settings {
    config: EncoderConfig,
    aq_on: bool,
    aq: AqParams,
}

impl Default for Settings {
    fn default() -> Self {
        let config = EncoderConfig::default();
        Self { aq_on: config.format.aq.is_some(), aq: config.format.aq.unwrap_or_default(), config }
    }
}

struct Opt {
    key: &'static str,
    get: fn(&Settings, Python<'_>) -> PyResult<PyObject>,
    set: fn(&mut Settings, &Bound<'_, PyAny>) -> PyResult<()>,
}

/// An option that is one field, converted as it is.
macro_rules! field {
    ($key:literal, $($path:ident).+) => {
        Opt {
            key: $key,
            get: |s, py| s.$($path).+.into_py_any(py),
            set: |s, v| {
                s.$($path).+ = v.extract()?;
                Ok(())
            },
        }
    };
}

/// An option that is one field spelled as a name: `name` gives the spelling, `parse` reads
/// it back or says why it cannot.
macro_rules! named {
    ($key:literal, $($path:ident).+, $name:expr, $parse:expr) => {
        Opt {
            key: $key,
            get: |s, py| $name(&s.$($path).+).into_py_any(py),
            set: |s, v| {
                s.$($path).+ = $parse(&v.extract::<String>()?).map_err(input_error)?;
                Ok(())
            },
        }
    };
}

const OPTIONS: &[Opt] = &[
    field!("qp", config.format.qp),
    field!("base_ratio", config.search.base_ratio),
    field!("subdiv", config.format.subdiv_iterations),
    named!("scheme", config.format.scheme, SchemeChoice::spec, SchemeChoice::parse),
    field!("bits", config.format.bits),
    field!("base_bits", config.format.base_bits),
    field!("normal_only", config.format.normal_only),
    field!("intra_period", config.search.intra_period),
    named!("inter", config.search.inter, inter_name, inter_of),
    field!("rd_slope", config.search.rd_slope_db),
    field!("refit", config.search.refit),
    field!("fold_repair", config.search.fold_repair),
    field!("rigid_align", config.search.rigid_align),
    field!("motion_parts", config.search.motion_parts),
    field!("refresh", config.search.refresh),
    field!("references", config.search.references),
    field!("intra_reference", config.search.intra_reference),
    field!("always_try_intra", config.search.always_try_intra),
    field!("intra_check_db", config.search.intra_check_db),
    named!("lifting", config.format.lifting, |l: &LiftingChoice| l.name(), lifting_of),
    field!("aq", aq_on),
    field!("aq_alpha", aq.alpha),
    field!("aq_delta", aq.delta),
    field!("aq_h", aq.h),
];

/// The name `--inter` gives to predicting constant connectivity only (no anchor stages).
const NO_ANCHOR: &str = "none";

fn inter_name(inter: &Option<AnchorStages>) -> &'static str {
    inter.map_or(NO_ANCHOR, AnchorStages::name)
}

fn inter_of(name: &str) -> Result<Option<AnchorStages>, String> {
    match name {
        NO_ANCHOR => Ok(None),
        _ => AnchorStages::from_name(name)
            .map(Some)
            .ok_or_else(|| format!("unknown inter mode {name:?} (one of {})", inter_modes().join(", "))),
    }
}

fn lifting_of(name: &str) -> Result<LiftingChoice, String> {
    LiftingChoice::from_name(name).ok_or_else(|| format!("unknown lifting {name:?} (one of {})", LiftingChoice::NAMES.join(", ")))
}

/// The `inter` option's values: no anchor, then the anchor's stages.
pub fn inter_modes() -> Vec<&'static str> {
    std::iter::once(NO_ANCHOR).chain(AnchorStages::NAMES).collect()
}

/// The encoder configuration from a dict of options named as in [`default_options`]; the
/// options not given keep their defaults. Errors on an unknown name or an invalid value.
pub fn config_of(options: &Bound<'_, PyDict>) -> PyResult<EncoderConfig> {
    let mut s = Settings::default();
    for (key, value) in options.iter() {
        let key: String = key.extract()?;
        let opt = OPTIONS.iter().find(|o| o.key == key);
        let opt = opt.ok_or_else(|| input_error(format!("unknown encoder option {key:?}")))?;
        (opt.set)(&mut s, &value)?;
    }
    s.config.format.aq = s.aq_on.then_some(s.aq);
    s.config.validate().map_err(|e| core_error(e.into()))?;
    Ok(s.config)
}

/// The encoder's default options, by name, in the order of [`OPTIONS`].
#[pyfunction]
pub fn default_options(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let s = Settings::default();
    let d = PyDict::new(py);
    for o in OPTIONS {
        d.set_item(o.key, (o.get)(&s, py)?)?;
    }
    Ok(d)
}

/// The base mesh ratio the encoder takes at `qp` when none is given
/// ([`encode::base_ratio_for_qp`]), so that the command line's help can state the rule.
#[pyfunction]
pub fn base_ratio_for_qp(qp: i32) -> f64 {
    encode::base_ratio_for_qp(qp)
}

/// Registers the option functions and the names of the choice options.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(default_options, m)?)?;
    m.add_function(wrap_pyfunction!(base_ratio_for_qp, m)?)?;
    m.add("QP_RANGE", (*QP_RANGE.start(), *QP_RANGE.end()))?;
    m.add("INTER_MODES", inter_modes())?;
    m.add("LIFTINGS", LiftingChoice::NAMES.to_vec())?;
    Ok(())
}
