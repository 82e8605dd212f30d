//! `rbprops init-spec`: a campaign spec (the TOML `frf-sim` and `model-check` read) from a
//! recording. Sensors, channel ids, directions, excitations and set-ups are written
//! exactly as the recording names and places them, so `model-check` matches every
//! recorded FRF to the spec by id. What a recording cannot tell — the body's inertia, the
//! suspension, the damping — is written as a placeholder (`nan`, which the spec's
//! validation refuses) with a comment marked [`PLACEHOLDER_MARK`] saying what to fill in.

use anyhow::{bail, Result};
use rbprops_core::{Channel, FrfSet, Geometry, Vec3};
use std::fmt::Write as _;

/// Marks every line a person must fill in.
pub const PLACEHOLDER_MARK: &str = "FILL IN";

/// Smallest |det| of a point's three channel directions for them to be one triaxial
/// sensor (the spec's own limit on `axes`); below it they are written as uniaxial sensors.
const TRIAXIAL_MIN_DET: f64 = 0.5;

/// Appended to a spec's validation error when the text still holds init-spec placeholders.
pub fn placeholder_hint(spec_text: &str) -> &'static str {
    if spec_text.contains(PLACEHOLDER_MARK) {
        " (the spec still holds `rbprops init-spec` placeholders marked FILL IN: give the body, suspension and damping their values)"
    } else {
        ""
    }
}

/// A model-check error, with the way out when the recording's ids are not the spec's.
pub fn mismatch_hint(e: rbprops_check::CheckError, recording: &str) -> anyhow::Error {
    match e {
        rbprops_check::CheckError::Mismatch(_) => anyhow::anyhow!(
            "{e}\nhint: `rbprops init-spec {recording}` writes a spec with the recording's own channel and excitation ids; copy the body and suspension into it"
        ),
        e => e.into(),
    }
}

/// A TOML string literal.
fn q(s: &str) -> String {
    toml::Value::String(s.to_string()).to_string()
}

/// A float in shortest round-trip form (reads back bit for bit).
/// (Rust's `Debug` form: `0.1`, `-0.0`, `1e-5`, all valid TOML floats.)
fn num(x: f64) -> String {
    format!("{x:?}")
}

fn vec3(v: &Vec3) -> String {
    format!("[{}, {}, {}]", num(v.x), num(v.y), num(v.z))
}

/// The spec text for a recording's geometry and FRFs. `source` (the file name) goes into
/// the header and the campaign name.
pub fn spec_text(geometry: &Geometry, frf: &FrfSet, source: &str, name: &str) -> Result<String> {
    if geometry.channels.is_empty() || geometry.excitations.is_empty() {
        bail!("{source}: the recording has no channels or no excitations");
    }
    let f = &frf.frequency_hz;
    let (Some(&f0), Some(&f1)) = (f.first(), f.last()) else {
        bail!("{source}: the recording has an empty frequency axis");
    };
    let n = f.len();
    let uniform = n < 3 || {
        let step = (f1 - f0) / (n - 1) as f64;
        f.iter()
            .enumerate()
            .all(|(l, &x)| (x - (f0 + l as f64 * step)).abs() <= 1e-9 * f1.abs().max(1.0))
    };
    let mut s = String::new();
    let m = PLACEHOLDER_MARK;
    let _ = writeln!(
        s,
        "# Campaign spec written by `rbprops init-spec` from {source}.\n\
         # Sensors, channels, excitations and set-ups are the recording's, with its ids: keep\n\
         # them as they are so model-check matches each recorded FRF to the spec.\n\
         # Lines marked `{m}` are placeholders (nan) the recording cannot tell: the body's\n\
         # mass, centre of mass and inertia, each set-up's springs and the damping. The spec\n\
         # is refused until every one of them holds a number.\n\
         # Units: SI (m, kg, s, N), frequencies in Hz; gravity along −z unless `up` says otherwise."
    );
    let _ = writeln!(s, "name = {}", q(name));
    let _ = writeln!(
        s,
        "description = {}",
        q(&format!(
            "written by rbprops init-spec from {source}; body and suspension to fill in"
        ))
    );
    let _ = writeln!(s, "seed = 0");
    let _ = writeln!(s, "quantity = {}", q(frf.quantity.name()));
    let _ = writeln!(
        s,
        "# up = [0.0, 0.0, 1.0]   # the upward unit vector of the recording's frame, if not +z"
    );
    let _ = writeln!(s, "\n[frequency]");
    if !uniform {
        let _ = writeln!(
            s,
            "# The recording's axis is not uniform ({n} lines): model-check uses the recording's\n\
             # own axis; frf-sim simulates this uniform one."
        );
    }
    let _ = writeln!(
        s,
        "start_hz = {}\nstop_hz = {}\nlines = {n}",
        num(f0),
        num(f1)
    );
    let _ = writeln!(
        s,
        "\n[body]\n\
         # {m}: the article's mass (weigh it), centre of mass in the recording's frame, and\n\
         # the inertia at the centre of mass: moments and CAD products (J_xy = ∫xy dm), or the\n\
         # whole tensor as inertia_cm_kg_m2 = [[..], [..], [..]] instead of both.\n\
         mass_kg = nan                                 # {m} (kg)\n\
         com_m = [nan, nan, nan]                       # {m} (m)\n\
         moments_kg_m2 = [nan, nan, nan]               # {m} (kg m²)\n\
         products_kg_m2 = {{ xy = nan, xz = nan, yz = nan }}   # {m} (kg m²; 0 for principal axes)"
    );
    for su in &geometry.setups {
        let _ = writeln!(
            s,
            "\n[[setup]]\nid = {}\ndescription = {}\n\
             # {m}: one [[setup.spring]] per suspension element (cord, spring, foam block): where\n\
             # it holds the body (m) and its stiffness along x, y, z (N/m), or a full symmetric\n\
             # stiffness_matrix_n_per_m. Copy the block for each element.\n\
             [[setup.spring]]\n\
             at_m = [nan, nan, nan]                        # {m}\n\
             stiffness_n_per_m = [nan, nan, nan]           # {m}",
            q(&su.id),
            q(&su.description)
        );
    }
    for sensor in sensors(geometry) {
        s.push('\n');
        s += &sensor;
    }
    for e in &geometry.excitations {
        let _ = writeln!(
            s,
            "\n[[excitation]]\nid = {}\npoint = {}\nat_m = {}\ndirection = {}\nsetup = {}",
            q(&e.id),
            q(&e.point),
            vec3(&e.position),
            vec3(&e.direction),
            q(&e.setup)
        );
    }
    let _ = writeln!(
        s,
        "\n[damping]\n\
         # {m}: the modal damping ratio of the suspension modes (from modal-fit's damping_ratio,\n\
         # say), or `ratios` = six values by ascending mode frequency, or model = \"proportional\"\n\
         # with alpha/beta.\n\
         model = \"modal\"\n\
         ratio = nan                                   # {m}\n\
         \n[noise]\n\
         # model-check estimates the recording's noise itself; frf-sim adds this much.\n\
         relative = 0.0\nfloor = 0.0"
    );
    Ok(s)
}

/// The `[[sensor]]` blocks: the channels grouped by point in recording order; a point
/// with three channels whose directions span space is one triaxial sensor, any other
/// channel is a uniaxial sensor. Ids are always given explicitly (`channels`).
fn sensors(g: &Geometry) -> Vec<String> {
    let mut points: Vec<(&str, Vec<&Channel>)> = Vec::new();
    for c in &g.channels {
        match points.iter_mut().find(|(p, _)| *p == c.point) {
            Some((_, v)) => v.push(c),
            None => points.push((&c.point, vec![c])),
        }
    }
    let mut out = Vec::new();
    for (point, chans) in points {
        let triaxial = chans.len() == 3 && {
            let m = rbprops_core::Mat3::from_rows(&[
                chans[0].direction.transpose(),
                chans[1].direction.transpose(),
                chans[2].direction.transpose(),
            ]);
            m.determinant().abs() >= TRIAXIAL_MIN_DET
                && chans.iter().all(|c| c.position == chans[0].position)
        };
        if triaxial {
            out.push(format!(
                "[[sensor]]\nid = {}\nkind = \"triaxial\"\nat_m = {}\n\
                 axes = [{}, {}, {}]\nchannels = [{}, {}, {}]\n",
                q(point),
                vec3(&chans[0].position),
                vec3(&chans[0].direction),
                vec3(&chans[1].direction),
                vec3(&chans[2].direction),
                q(&chans[0].id),
                q(&chans[1].id),
                q(&chans[2].id)
            ));
        } else {
            for c in &chans {
                // One sensor per channel: the point's id when it is the point's only
                // channel, else the channel's id (sensor ids are unique).
                let id = if chans.len() == 1 { point } else { &c.id };
                out.push(format!(
                    "[[sensor]]\nid = {}\nkind = \"uniaxial\"\nat_m = {}\ndirection = {}\n\
                     channels = [{}]\n",
                    q(id),
                    vec3(&c.position),
                    vec3(&c.direction),
                    q(&c.id)
                ));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floats_read_back_bit_for_bit() {
        for x in [0.1, -0.0, 1e-5, 2.5e-300, 0.17725, 1.0 / 3.0, 12.5] {
            let v: toml::Table = toml::from_str(&format!("x = {}", num(x))).unwrap();
            assert_eq!(v["x"].as_float().unwrap().to_bits(), x.to_bits(), "{x}");
        }
    }
}
