//! Scale factors of a dataset 58 to SI: ordinate (records 9 and 10) and abscissa
//! (record 8), by the precedence of `docs/formats.md` (units label, data type, dataset 164).

use crate::error::{DatasetLocation, UffError};
use crate::model::*;
use crate::units::{is_unset, parse_label, Unit};
use rbprops_core::Quantity;

/// Conversion of one FRF record to SI and its quantity.
pub(super) struct Scaling {
    pub(super) quantity: Quantity,
    pub(super) value: f64,
    pub(super) abscissa: f64,
}

pub(super) fn data_type_name(t: i64) -> &'static str {
    match t {
        0 => "unknown",
        1 => "general",
        8 => "displacement",
        9 => "reaction force",
        11 => "velocity",
        12 => "acceleration",
        13 => "excitation force",
        17 => "time",
        18 => "frequency",
        _ => "other",
    }
}

/// What a units label says, or why it says nothing usable.
pub(super) fn read_label(axis: &AxisInfo) -> Option<Result<Unit, String>> {
    if is_unset(&axis.units_label) {
        return None;
    }
    Some(parse_label(&axis.units_label).map_err(|e| e.0))
}

/// Scale factors of one dataset 58 to SI, by the precedence documented in
/// `docs/formats.md`: the units label of an axis when it parses and agrees in dimension
/// with the specific data type of records 8–10; otherwise the data type with the file's
/// dataset 164 units (a label that cannot be read, or that contradicts the data type, is a
/// warning naming both); an error only when neither determines the unit.
pub(super) fn scaling(
    file: &str,
    at: &DatasetLocation,
    f: &Function,
    length_si: f64,
    force_si: f64,
    warn: &mut Vec<String>,
) -> Result<Scaling, UffError> {
    let err = |field: &str, problem: String| UffError::Field {
        file: file.to_string(),
        at: at.clone(),
        field: field.to_string(),
        problem,
    };
    let (quantity, num_factor, whole) = numerator_scale(&err, f, length_si, warn)?;
    // The denominator (record 10), unless the numerator label already holds the whole FRF.
    let den_factor = if whole {
        1.0
    } else {
        denominator_scale(&err, f, force_si, warn)?
    };
    let abscissa = abscissa_factor(file, at, f, warn)?;
    Ok(Scaling {
        quantity,
        value: num_factor / den_factor,
        abscissa,
    })
}

/// The numerator's quantity and factor to SI (record 9), and whether its units label
/// holds the whole FRF (motion per force).
pub(super) fn numerator_scale(
    err: &dyn Fn(&str, String) -> UffError,
    f: &Function,
    length_si: f64,
    warn: &mut Vec<String>,
) -> Result<(Quantity, f64, bool), UffError> {
    let force = Unit::base(1.0, 0, 1, 0);
    let motion = |q: Quantity| Unit::base(1.0, 1, 0, -q.order());
    let quantities = [
        Quantity::Receptance,
        Quantity::Mobility,
        Quantity::Accelerance,
    ];
    let num_field = "record 9 (ordinate numerator)";
    let t = f.numerator.data_type;
    let by_type = match t {
        8 => Some(Quantity::Receptance),
        11 => Some(Quantity::Mobility),
        12 => Some(Quantity::Accelerance),
        _ => None,
    };
    // The label's reading: (quantity, factor, label is the whole FRF).
    let by_label = read_label(&f.numerator).map(|r| {
        r.and_then(|u| {
            quantities
                .iter()
                .find_map(|&q| {
                    if u.same_dimension(&motion(q)) {
                        Some((q, u.factor, false))
                    } else if u.same_dimension(&motion(q).times(force.powi(-1))) {
                        Some((q, u.factor, true))
                    } else {
                        None
                    }
                })
                .ok_or_else(|| {
                    format!(
                        "{} is not a displacement, velocity or acceleration, nor one per force",
                        u.dimension()
                    )
                })
        })
    });
    let label = &f.numerator.units_label;
    Ok(match (by_type, by_label) {
        (Some(q), None) => (q, length_si, false),
        (Some(q), Some(Ok((lq, factor, whole)))) if lq == q => (q, factor, whole),
        (Some(q), Some(Ok((lq, _, _)))) => {
            warn.push(format!(
                "{num_field}: units label '{label}' ({}) contradicts data type {t} ({}): the data type is used, with the file's units",
                lq.name(),
                data_type_name(t)
            ));
            (q, length_si, false)
        }
        (Some(q), Some(Err(why))) => {
            warn.push(format!(
                "{num_field}: units label '{label}' is not used ({why}): data type {t} ({}) with the file's units instead",
                data_type_name(t)
            ));
            (q, length_si, false)
        }
        (None, Some(Ok((lq, factor, whole)))) if matches!(t, 0 | 1) => (lq, factor, whole),
        (None, Some(Ok((lq, _, _)))) => {
            return Err(err(
                &format!("{num_field} field 1 (specific data type)"),
                format!(
                    "data type {t} ({}) is not displacement (8), velocity (11) or acceleration (12), though the units label '{label}' reads as {}",
                    data_type_name(t),
                    lq.name()
                ),
            ))
        }
        (None, Some(Err(why))) => {
            return Err(err(
                &format!("{num_field} field 6 (units label)"),
                format!(
                    "units label '{label}' is not understood ({why}) and data type {t} ({}) does not say displacement (8), velocity (11) or acceleration (12): nothing determines the unit",
                    data_type_name(t)
                ),
            ))
        }
        (None, None) => {
            return Err(err(
                &format!("{num_field} field 1 (specific data type)"),
                format!(
                    "data type {t} ({}) without a units label: nothing says displacement, velocity or acceleration",
                    data_type_name(t)
                ),
            ))
        }
    })
}

/// The denominator's factor to SI (record 10): a force.
pub(super) fn denominator_scale(
    err: &dyn Fn(&str, String) -> UffError,
    f: &Function,
    force_si: f64,
    warn: &mut Vec<String>,
) -> Result<f64, UffError> {
    let force = Unit::base(1.0, 0, 1, 0);
    let den_field = "record 10 (ordinate denominator)";
    let t = f.denominator.data_type;
    let label = &f.denominator.units_label;
    let typed_force = matches!(t, 9 | 13);
    Ok(match read_label(&f.denominator) {
        Some(Ok(u)) if u.same_dimension(&force) && (typed_force || matches!(t, 0 | 1)) => u.factor,
        Some(Ok(u)) if typed_force => {
            warn.push(format!(
                "{den_field}: units label '{label}' ({}) contradicts data type {t} ({}): the data type is used, with the file's units",
                u.dimension(),
                data_type_name(t)
            ));
            force_si
        }
        Some(Err(why)) if typed_force => {
            warn.push(format!(
                "{den_field}: units label '{label}' is not used ({why}): data type {t} ({}) with the file's units instead",
                data_type_name(t)
            ));
            force_si
        }
        None if typed_force => force_si,
        // Type 0/1 and no usable label: the function type (4, FRF) says force.
        None if matches!(t, 0 | 1) => {
            warn.push(format!(
                "{den_field}: data type {t} ({}) without a units label: taken as a force in the file's units (function type 4 is an FRF)",
                data_type_name(t)
            ));
            force_si
        }
        other => {
            let why = match other {
                Some(Ok(u)) => format!("units label '{label}' is {}", u.dimension()),
                Some(Err(why)) => format!("units label '{label}' is not understood ({why})"),
                None => "no units label".to_string(),
            };
            return Err(err(
                &format!("{den_field} field 1 (specific data type)"),
                format!(
                    "data type {t} ({}) is not an excitation force (13) or reaction force (9), and {why}",
                    data_type_name(t)
                ),
            ));
        }
    })
}

/// Hz per abscissa unit of a dataset 58 (record 8), by the same precedence.
pub(super) fn abscissa_factor(
    file: &str,
    at: &DatasetLocation,
    f: &Function,
    warn: &mut Vec<String>,
) -> Result<f64, UffError> {
    let ab_field = "record 8 (abscissa)";
    let t = f.abscissa_axis.data_type;
    let label = &f.abscissa_axis.units_label;
    let is_frequency = |u: &Unit| u.length == 0 && u.force == 0 && u.time == -1;
    match (t, read_label(&f.abscissa_axis)) {
        (18 | 0 | 1, Some(Ok(u))) if is_frequency(&u) => Ok(u.factor),
        (18 | 0, None) => Ok(1.0),
        (18 | 0, Some(Ok(u))) => {
            warn.push(format!(
                "{ab_field}: units label '{label}' ({}) contradicts data type {t} ({}): taken in Hz",
                u.dimension(),
                data_type_name(t)
            ));
            Ok(1.0)
        }
        (18 | 0, Some(Err(why))) => {
            warn.push(format!(
                "{ab_field}: units label '{label}' is not used ({why}): taken in Hz"
            ));
            Ok(1.0)
        }
        (t, _) => Err(UffError::Field {
            file: file.to_string(),
            at: at.clone(),
            field: format!("{ab_field} field 1 (specific data type)"),
            problem: format!(
                "abscissa data type {t} ({}, units label '{label}') is not a frequency (18) in Hz",
                data_type_name(t)
            ),
        }),
    }
}
