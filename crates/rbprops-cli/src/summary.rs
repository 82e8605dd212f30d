//! One summary row per estimate: the table of campaigns, golden files and reports.

use anyhow::Result;
use rbprops_core::records::InertiaEstimate;
use rbprops_formats::{topics, RunRecord};
use serde::{Deserialize, Serialize};

/// A row of the summary table (CSV columns in this order).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct SummaryRow {
    /// Campaign name (from the spec, or the recording's file stem).
    pub campaign: String,
    /// Mode set: `ni` (automatic) or the manual set's label.
    pub set: String,
    /// Origin label (`geometry` or the point/channel id or coordinates).
    pub origin: String,
    /// Estimator (`bretl_conti`, `toivola_nuutila`, `mass_line`, `…_projected`, or `error`).
    pub method: String,
    /// Suspension set-up of the estimate.
    pub setup: String,
    /// Mass `m` (kg).
    pub mass_kg: f64,
    /// Centre of mass, x (m).
    pub com_x_m: f64,
    /// Centre of mass, y (m).
    pub com_y_m: f64,
    /// Centre of mass, z (m).
    pub com_z_m: f64,
    /// Moment `J_xx` about the CoM (kg m²).
    pub jxx: f64,
    /// Moment `J_yy` about the CoM (kg m²).
    pub jyy: f64,
    /// Moment `J_zz` about the CoM (kg m²).
    pub jzz: f64,
    /// Products of inertia (∫xy dm), not tensor entries.
    pub jxy: f64,
    /// `J_xz` (kg m²).
    pub jxz: f64,
    /// `J_yz` (kg m²).
    pub jyz: f64,
    /// Standard error of the mass (kg).
    pub mass_std_kg: f64,
    /// Norm of the CoM's standard errors, `√(σ_x² + σ_y² + σ_z²)` (m).
    pub com_std_m: f64,
    /// Relative mass error against the reference, when one is given.
    pub err_mass: Option<f64>,
    /// Relative CoM error `‖ĉ − c‖/‖c‖`.
    pub err_com: Option<f64>,
    /// Relative inertia error over `{Jxx Jxy Jxz Jyy Jyz Jzz}`.
    pub err_inertia: Option<f64>,
    /// Sum of the three relative errors.
    pub err_sum: Option<f64>,
    /// Mode numbers used, space separated.
    pub modes: String,
    /// The estimate's diagnostics that may change the answer (not its notes), each as
    /// one line, joined by ` | `.
    pub warnings: String,
    /// Model check against the nominal spec (campaigns with `nominal`; empty otherwise):
    /// the effects it names (accepted ids, ambiguous families as `a/b`).
    #[serde(default)]
    pub check_effects: String,
    /// χ²/ν of the nominal spec as given.
    #[serde(default)]
    pub check_chi2_nu_nominal: Option<f64>,
    /// χ²/ν of the baseline fit (nominal physics, fitted parameters) and of the final
    /// model; ≈ 1 means the residual is noise.
    #[serde(default)]
    pub check_chi2_nu_before: Option<f64>,
    /// χ²/ν of the final model.
    #[serde(default)]
    pub check_chi2_nu_after: Option<f64>,
    /// The final model's residual is consistent with the noise.
    #[serde(default)]
    pub check_noise_floor_reached: Option<bool>,
    /// The model check's one-line verdict (or `error: …`).
    #[serde(default)]
    pub check_verdict: String,
    /// The verdict as a short label (`clean, at the noise floor`, `channel_gain …`;
    /// `check failed`): what a table shows ([`crate::campaign::check_label`]).
    #[serde(default)]
    pub check_label: String,
}

impl SummaryRow {
    /// The row of one estimate (the check columns left empty; see [`Self::set_check`]).
    pub fn from_estimate(campaign: &str, set: &str, origin: &str, e: &InertiaEstimate) -> Self {
        let j = &e.inertia_cm_kg_m2;
        let p = &e.products_of_inertia_kg_m2;
        let s = &e.com_std_m;
        SummaryRow {
            campaign: campaign.into(),
            set: set.into(),
            origin: origin.into(),
            method: e.method.to_string(),
            setup: e.setup.clone(),
            mass_kg: e.mass_kg,
            com_x_m: e.com_m[0],
            com_y_m: e.com_m[1],
            com_z_m: e.com_m[2],
            jxx: j[0][0],
            jyy: j[1][1],
            jzz: j[2][2],
            jxy: p.xy,
            jxz: p.xz,
            jyz: p.yz,
            mass_std_kg: e.mass_std_kg,
            com_std_m: (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt(),
            err_mass: e.errors.map(|x| x.mass),
            err_com: e.errors.map(|x| x.com),
            err_inertia: e.errors.map(|x| x.inertia),
            err_sum: e.errors.map(|x| x.sum),
            modes: e
                .modes_used
                .iter()
                .map(|m| m.to_string())
                .collect::<Vec<_>>()
                .join(" "),
            warnings: e
                .diagnostics
                .iter()
                .filter(|d| crate::warnings::shown_by_default(d))
                .map(|d| d.line())
                .collect::<Vec<_>>()
                .join(" | "),
            ..Default::default()
        }
    }

    /// Fills the model check's columns.
    pub fn set_check(&mut self, c: &crate::campaign::CheckColumns) {
        self.check_effects = c.effects.clone();
        let failed = c.label == crate::campaign::CHECK_FAILED;
        self.check_chi2_nu_nominal = (!failed).then_some(c.chi2_nu_nominal);
        self.check_chi2_nu_before = (!failed).then_some(c.chi2_nu_before);
        self.check_chi2_nu_after = (!failed).then_some(c.chi2_nu_after);
        self.check_noise_floor_reached = (!failed).then_some(c.noise_floor_reached);
        self.check_verdict = c.verdict.clone();
        self.check_label = c.label.clone();
    }

    /// The numeric columns with their names (for tolerance checks).
    pub fn numbers(&self) -> Vec<(&'static str, Option<f64>)> {
        vec![
            ("mass_kg", Some(self.mass_kg)),
            ("com_x_m", Some(self.com_x_m)),
            ("com_y_m", Some(self.com_y_m)),
            ("com_z_m", Some(self.com_z_m)),
            ("jxx", Some(self.jxx)),
            ("jyy", Some(self.jyy)),
            ("jzz", Some(self.jzz)),
            ("jxy", Some(self.jxy)),
            ("jxz", Some(self.jxz)),
            ("jyz", Some(self.jyz)),
            ("err_mass", self.err_mass),
            ("err_com", self.err_com),
            ("err_inertia", self.err_inertia),
            ("err_sum", self.err_sum),
        ]
    }
}

/// The printed inertia properties of a row, as every table shows them: mass (kg) to
/// 4 decimals, the centre of mass in mm to 2, moments and products (kg m²) to 5.
pub struct PropertyCells {
    /// Mass (kg), 4 decimals.
    pub mass: String,
    /// Centre of mass (mm), 2 decimals each.
    pub com_mm: String,
    /// `J_xx J_yy J_zz` (kg m²), 5 decimals each.
    pub moments: String,
    /// `J_xy J_xz J_yz` (kg m²), 5 decimals each: products, not tensor entries.
    pub products: String,
}

impl SummaryRow {
    /// The row's properties formatted for a table cell each (HTML and Markdown alike).
    pub fn property_cells(&self) -> PropertyCells {
        PropertyCells {
            mass: format!("{:.4}", self.mass_kg),
            com_mm: format!(
                "{:.2}, {:.2}, {:.2}",
                1e3 * self.com_x_m,
                1e3 * self.com_y_m,
                1e3 * self.com_z_m
            ),
            moments: format!("{:.5} {:.5} {:.5}", self.jxx, self.jyy, self.jzz),
            products: format!("{:.5} {:.5} {:.5}", self.jxy, self.jxz, self.jyz),
        }
    }
}

/// Rows for every estimate in a run record.
pub fn rows(rec: &RunRecord, campaign: &str, set: &str, origin: &str) -> Result<Vec<SummaryRow>> {
    let est: Vec<InertiaEstimate> = rec.get(topics::ESTIMATES)?;
    Ok(est
        .iter()
        .map(|e| SummaryRow::from_estimate(campaign, set, origin, e))
        .collect())
}

/// CSV text of the rows (header included); floats in shortest round-trip form.
pub fn to_csv(rows: &[SummaryRow]) -> Result<String> {
    let mut w = csv::Writer::from_writer(Vec::new());
    for r in rows {
        w.serialize(r)?;
    }
    if rows.is_empty() {
        return Ok(String::new());
    }
    Ok(String::from_utf8(w.into_inner()?)?)
}

/// Rows of a summary CSV (the inverse of [`to_csv`]).
pub fn from_csv(text: &str) -> Result<Vec<SummaryRow>> {
    let mut r = csv::Reader::from_reader(text.as_bytes());
    Ok(r.deserialize().collect::<Result<Vec<SummaryRow>, _>>()?)
}

/// Compares rows with golden rows: same keys, every number within
/// `|a − b| ≤ abs_tol + rel_tol·|b|`. Returns a readable list of differences.
pub fn compare(
    actual: &[SummaryRow],
    golden: &[SummaryRow],
    rel_tol: f64,
    abs_tol: f64,
) -> Vec<String> {
    let key = |r: &SummaryRow| {
        format!(
            "{}/{}/{}/{}/{}",
            r.campaign, r.set, r.origin, r.method, r.setup
        )
    };
    let mut diffs = Vec::new();
    for g in golden {
        let Some(a) = actual.iter().find(|a| key(a) == key(g)) else {
            diffs.push(format!("{}: missing from this run", key(g)));
            continue;
        };
        for ((name, x), (_, y)) in a.numbers().into_iter().zip(g.numbers()) {
            match (x, y) {
                (Some(x), Some(y)) if (x - y).abs() <= abs_tol + rel_tol * y.abs() => {}
                (None, None) => {}
                (x, y) => diffs.push(format!("{}: {name} = {x:?}, golden {y:?} (tolerance {rel_tol:e} rel + {abs_tol:e} abs)", key(g))),
            }
        }
        if a.modes != g.modes {
            diffs.push(format!(
                "{}: modes used '{}', golden '{}'",
                key(g),
                a.modes,
                g.modes
            ));
        }
    }
    for a in actual {
        if !golden.iter().any(|g| key(g) == key(a)) {
            diffs.push(format!("{}: new row, not in the golden file", key(a)));
        }
    }
    diffs
}
