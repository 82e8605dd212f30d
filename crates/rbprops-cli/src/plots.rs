//! Figures shared by several stages (FRF overlays), built on `rbprops-plot`.

use anyhow::Result;
use rbprops_core::{FrfSet, Geometry};
use rbprops_plot::{line_plot, LinePlot, Scale, Series};

/// One figure per excitation: |FRF| of every channel (the paper's Figs. 3 and 10).
pub fn frf_magnitudes(geometry: &Geometry, frf: &FrfSet) -> Result<Vec<(String, String)>> {
    let mut out = Vec::new();
    for (e, exc) in geometry.excitations.iter().enumerate() {
        let series = geometry
            .channels
            .iter()
            .enumerate()
            .map(|(c, ch)| {
                Series::new(
                    ch.id.clone(),
                    frf.frequency_hz.clone(),
                    frf.frf(e, c).iter().map(|v| v.norm()).collect(),
                )
            })
            .collect();
        let plot = LinePlot {
            title: format!(
                "{} FRFs, excitation {} (set-up {})",
                frf.quantity.name(),
                exc.id,
                exc.setup
            ),
            x_label: "Frequency [Hz]".into(),
            y_label: format!("|H| [{}]", frf.quantity.unit()),
            y_scale: Scale::Log10,
            series,
            ..Default::default()
        };
        out.push((format!("frf_{}.svg", sanitize(&exc.id)), line_plot(&plot)?));
    }
    Ok(out)
}

/// A file-name-safe version of an id.
pub fn sanitize(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}
