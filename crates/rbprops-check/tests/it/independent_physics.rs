//! The model check on recordings made by the independent reference generator
//! (`scripts/refgen`, Python/numpy, its own formulation from the potential energy and a
//! state-space eigen-solution), not by rbprops-sim: general viscous damping (full 3×3
//! dashpots at the mounts), two elastic modes above the band, and dashpots among other
//! effects. Python is found through `RBPROPS_PYTHON`; without numpy the tests are skipped
//! with a note, unless `RBPROPS_REQUIRE_PYTHON` is set (as CI does).
//!
//! Recordings are small (400 lines × 9 channels × 3 excitations) to keep CI cheap.
//! The noise is the generator's, 1 % relative, and is given to the check (σ known), so
//! χ²/ν after the refit must fall inside the check's own noise band: with ν ≈ 2·10⁴
//! degrees of freedom its half-width 3√(2/ν) ≈ 0.03 is the 3σ spread of χ²/ν for a
//! correct model.

use crate::common::given_noise;
use rbprops_check::{check, ModelCheckReport};
use rbprops_core::{c64, FrfSet, Geometry};
use rbprops_sim::CampaignSpec;
use rbprops_testkit::{python, refgen as refgen_command, repo_root, NUMPY_PYUFF};

const REL: f64 = 0.01;

/// The nominal model: Test Case II as written (modal damping 1.5 %), `lines` lines.
fn nominal(lines: usize) -> CampaignSpec {
    let mut s = CampaignSpec::from_toml_str(rbprops_sim::example("test-case-2").unwrap()).unwrap();
    s.frequency.lines = lines;
    s
}

/// A recording of `case` (a refgen example) with `--set` changes, as the nominal
/// spec's geometry and an FRF set in its channel/excitation order.
fn refgen(
    py: &str,
    case: &str,
    sets: &[&str],
    seed: u64,
    nominal: &CampaignSpec,
) -> (Geometry, FrfSet) {
    let dir = std::env::temp_dir().join(format!(
        "rbprops-indep-{}-{case}-{seed}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("rec.json");
    let mut cmd = refgen_command(py);
    cmd.current_dir(repo_root())
        .arg(format!("scripts/refgen/examples/{case}.toml"))
        .args(["--seed", &seed.to_string(), "--quiet", "-o"])
        .arg(&out)
        .args([
            "--set",
            &format!("frequency.lines={}", nominal.frequency.lines),
        ]);
    for s in sets {
        cmd.args(["--set", s]);
    }
    let st = cmd.output().unwrap();
    assert!(
        st.status.success(),
        "refgen failed: {}",
        String::from_utf8_lossy(&st.stderr)
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&out).unwrap()).unwrap();
    std::fs::remove_dir_all(&dir).ok();
    let g = nominal.geometry().unwrap();
    let f: Vec<f64> = serde_json::from_value(j["frequency_hz"].clone()).unwrap();
    let ids = |key: &str| -> Vec<String> {
        j[key]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["id"].as_str().unwrap().to_string())
            .collect()
    };
    let (chs, exs) = (ids("channels"), ids("excitations"));
    let mut frf = FrfSet::zeros(
        nominal.quantity,
        f.clone(),
        g.excitations.len(),
        g.channels.len(),
    );
    let nl = f.len();
    for (e, ex) in g.excitations.iter().enumerate() {
        let je = exs.iter().position(|x| *x == ex.id).unwrap();
        for (c, ch) in g.channels.iter().enumerate() {
            let jc = chs.iter().position(|x| *x == ch.id).unwrap();
            for l in 0..nl {
                frf.values[(e * g.channels.len() + c) * nl + l] = c64::new(
                    j["re"][je][jc][l].as_f64().unwrap(),
                    j["im"][je][jc][l].as_f64().unwrap(),
                );
            }
        }
    }
    (g, frf)
}

fn named(r: &ModelCheckReport) -> Vec<String> {
    let mut v: Vec<String> = r.accepted.iter().map(|a| a.id.clone()).collect();
    for f in &r.ambiguous {
        v.extend(f.ids.iter().cloned());
    }
    v
}

fn summary(label: &str, r: &ModelCheckReport, t: std::time::Duration) {
    eprintln!(
        "{label}: named {:?}; χ²/ν {:.3} → {:.3} (band {:.3}–{:.3}); {:.1} s",
        named(r),
        r.chi2_nu_before,
        r.chi2_nu_after,
        r.noise_band[0],
        r.noise_band[1],
        t.as_secs_f64()
    );
}

/// A recording of the generator's springs (`tc2-springs`, 400 lines) at 1 % noise in
/// float32, as the combination study draws them, with the effects `sets`: the nominal,
/// its geometry and the FRFs (`None` without Python).
fn springs_study_recording(sets: &[&str], seed: u64) -> Option<(CampaignSpec, Geometry, FrfSet)> {
    let py = python(NUMPY_PYUFF)?;
    let nom = nominal(400);
    let all: Vec<&str> = [
        "noise.relative=0.01",
        "noise.floor=0.0",
        "output.precision=\"float32\"",
    ]
    .into_iter()
    .chain(sets.iter().copied())
    .collect();
    let (g, frf) = refgen(&py, "tc2-springs", &all, seed, &nom);
    Some((nom, g, frf))
}

/// The check with its default options (noise estimated from the data), its summary
/// printed under `label`.
fn checked_on_data_noise(
    label: &str,
    nom: &CampaignSpec,
    g: &Geometry,
    frf: &FrfSet,
) -> ModelCheckReport {
    let t0 = std::time::Instant::now();
    let r = check(nom, g, frf, &rbprops_check::CheckOptions::default())
        .unwrap()
        .report;
    summary(label, &r, t0.elapsed());
    r
}

/// Runs the check and asserts: exactly the expected ids named (each may appear inside an
/// ambiguity family, `allowed` lists the family members that are acceptable), nothing
/// else, and χ²/ν after the refit inside the noise band.
fn assert_explained(
    label: &str,
    nom: &CampaignSpec,
    g: &Geometry,
    frf: &FrfSet,
    expected: &[&str],
    allowed: &[&str],
) -> ModelCheckReport {
    assert_explained_with(label, nom, g, frf, expected, allowed, REL)
}

fn assert_explained_with(
    label: &str,
    nom: &CampaignSpec,
    g: &Geometry,
    frf: &FrfSet,
    expected: &[&str],
    allowed: &[&str],
    rel: f64,
) -> ModelCheckReport {
    let t0 = std::time::Instant::now();
    let mut opts = given_noise(REL, g.channels.len());
    if let Some(n) = &mut opts.noise {
        n.relative = vec![rel; g.channels.len()];
    }
    let r = check(nom, g, frf, &opts).unwrap().report;
    summary(label, &r, t0.elapsed());
    let ids = named(&r);
    for e in expected {
        assert!(
            ids.iter().any(|i| i == e),
            "{label}: {e} not named: {}",
            r.verdict
        );
    }
    let stray: Vec<&String> = ids
        .iter()
        .filter(|i| !expected.contains(&i.as_str()) && !allowed.contains(&i.as_str()))
        .collect();
    assert!(
        stray.is_empty(),
        "{label}: false claims {stray:?}: {}",
        r.verdict
    );
    crate::common::assert_chi2_in_band(label, &r);
    r
}

/// Anisotropic dashpots (full symmetric 3×3 at each mount, no modal damping): complex
/// modes, pole damping 3–7 %. The general viscous damping explains them to the noise.
#[test]
fn general_dashpots_are_named_and_fitted_to_the_noise() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let (g, frf) = refgen(
        &py,
        "tc2-dashpots",
        &[&format!("noise.relative={REL}")],
        4,
        &nom,
    );
    assert_explained(
        "dashpots",
        &nom,
        &g,
        &frf,
        &["nonproportional_damping"],
        &[],
    );
}

/// Three effects at once: the anisotropic dashpots, sensor 2 misoriented by 0.03 rad
/// about x, and force 2's gauge reading 4 % high. Each named, nothing else (a hysteretic
/// loss was once claimed next to the viscous model), χ²/ν inside the band.
#[test]
fn dashpots_among_other_effects_are_separated() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let (g, frf) = refgen(
        &py,
        "tc2-dashpots",
        &[
            &format!("noise.relative={REL}"),
            "sensor.2.misorientation_rad=[0.03,0.0,0.0]",
            "excitation.force2.force_gauge_gain=1.04",
        ],
        5,
        &nom,
    );
    assert_explained(
        "dashpots + misorientation + gauge gain",
        &nom,
        &g,
        &frf,
        &[
            "nonproportional_damping",
            "sensor_misorientation",
            "excitation_gain",
        ],
        &[],
    );
}

/// Two elastic modes above the band (37.5 and 50 Hz, 3× and 4× its top) with different
/// shapes, at 1 % noise: named as residual flexibility or as an elastic mode above the
/// band (the two describe the same physics here, and which one the selection takes
/// depends on the recording: with the same code, this seed gave `residual_flexibility`
/// in one Python environment and `elastic_mode` at 37.5 Hz, χ²/ν 23.5 → 1.001, in a
/// newer one), nothing else, χ²/ν inside the band.
#[test]
fn two_elastic_modes_above_the_band_are_explained() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let (g, frf) = refgen(
        &py,
        "tc2-elastic-above",
        &[&format!("noise.relative={REL}")],
        6,
        &nom,
    );
    let r = assert_explained(
        "two elastic modes above the band",
        &nom,
        &g,
        &frf,
        &[],
        &["residual_flexibility", "elastic_mode"],
    );
    assert_out_of_band_modes_named(&r, &frf, 1);
}

/// The same two modes on an exact recording (double precision, no noise, 200 lines)
/// with the noise estimated from the data, as a user runs the check: the first pass
/// reaches far below its data-only noise, the noise is re-estimated from its residual
/// (18 000 times smaller in χ²) and the check runs again. That second pass refits each
/// effect also from the first pass's model; it used to start there with the second
/// term's frequency and damping at neutral (the screening drops them: no signature
/// while the residues are zero), 1e11 times that model's χ², and ended at χ²/ν 3.4e5,
/// "not at the noise floor". Now it starts from the first pass's model itself.
#[test]
fn two_elastic_modes_above_the_band_on_exact_data_reach_the_floor() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(200);
    let (g, frf) = refgen(&py, "tc2-elastic-above", &[], 5, &nom);
    let r = checked_on_data_noise("two elastic modes above the band, exact", &nom, &g, &frf);
    assert_out_of_band_modes_named(&r, &frf, 2);
    assert!(r.noise_floor_reached, "{}", r.verdict);
}

/// At least `min_terms` terms (an ambiguous family counts as one), all of the
/// out-of-band family, and every elastic mode named for it sits above the band (not an
/// in-band resonance the data do not have).
fn assert_out_of_band_modes_named(r: &ModelCheckReport, frf: &FrfSet, min_terms: usize) {
    let stray: Vec<String> = named(r)
        .into_iter()
        .filter(|i| !i.starts_with("residual_flexibility") && !i.starts_with("elastic_mode"))
        .collect();
    assert!(stray.is_empty(), "false claims {stray:?}: {}", r.verdict);
    let terms = r.accepted.len() + r.ambiguous.len();
    assert!(
        terms >= min_terms,
        "{terms} terms, needs {min_terms}: {}",
        r.verdict
    );
    let top = frf.frequency_hz.last().copied().unwrap_or(0.0);
    for a in r
        .accepted
        .iter()
        .filter(|a| a.id.starts_with("elastic_mode"))
    {
        let f = a
            .parameters
            .iter()
            .find(|p| p.name == "frequency_hz")
            .map(|p| p.value)
            .expect("an elastic mode has a frequency");
        assert!(
            f > top,
            "elastic mode at {f} Hz, inside the band (top {top} Hz)"
        );
    }
}

/// The same two modes at 0.1 % noise, where χ²/ν of the baseline is 2250: one
/// out-of-band term with its general residue matrix still reaches the band (1.02), so a
/// second term is not needed at this noise (a longer study: 42 s, ignored in CI).
#[test]
#[ignore = "study (42 s): two out-of-band modes at 0.1 % noise"]
fn two_elastic_modes_above_the_band_at_low_noise() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let (g, frf) = refgen(&py, "tc2-elastic-above", &["noise.relative=0.001"], 6, &nom);
    let r = assert_explained_with(
        "two elastic modes, 0.1 % noise",
        &nom,
        &g,
        &frf,
        &[],
        &["residual_flexibility", "elastic_mode"],
        0.001,
    );
    assert_out_of_band_modes_named(&r, &frf, 1);
}

/// Three elastic modes just above the band (14, 19 and 27 Hz; top 12.5 Hz) with
/// different shapes, 0.1 % noise, 200 lines: no single out-of-band term can take them
/// (their ω² expansions differ channel by channel), so each needs its own pole. Named
/// only from the elastic family, at least three terms, and χ²/ν inside the band; each
/// elastic mode named sits above the band. Before further instances of the family
/// existed, this recording (at 400 lines) got one `elastic_mode` and one
/// `residual_flexibility`, then seven false effects and ended at χ²/ν 2.88; at 200
/// lines the third term was then still vetoed by the held-out excitation (an
/// excitation the others cannot predict, tested with a normal tail where its
/// estimation noise has a χ²₁'s: see `cv`), and spurious poles, a delay and a gain
/// filled in (χ²/ν 2.6). Now each of seeds 7, 8 (200 lines) and 7, 8, 9 (400 lines)
/// gets three terms of the family — the 14 Hz mode as the ambiguous pair
/// `elastic_mode` / `residual_flexibility` (one term, two descriptions), then
/// `residual_flexibility_2` and `_3` — and nothing else, χ²/ν in its band.
#[test]
fn three_elastic_modes_above_the_band_each_get_a_term() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(200);
    let (g, frf) = refgen(&py, "tc2-three-above", &["noise.relative=0.001"], 7, &nom);
    let family: Vec<String> = ["elastic_mode", "residual_flexibility"]
        .iter()
        .flat_map(|id| {
            (1..=1 + rbprops_check::candidates::FURTHER_INSTANCES).map(move |k| {
                if k == 1 {
                    id.to_string()
                } else {
                    format!("{id}_{k}")
                }
            })
        })
        .collect();
    let allowed: Vec<&str> = family.iter().map(String::as_str).collect();
    let r = assert_explained_with(
        "three elastic modes above the band",
        &nom,
        &g,
        &frf,
        &[],
        &allowed,
        0.001,
    );
    // An ambiguous family is one term in the model (its members are alternatives).
    assert_out_of_band_modes_named(&r, &frf, 3);
}

/// Six concealed effects at once (`tc2-six-effects`: sensor 2 misoriented ≈ 2°, sensor 3
/// displaced 5 mm, channel 1y gain +6 %, force 2's direction off by 5°, a 50 g gauge mass
/// under force 3, an in-band elastic mode at 10 Hz; 1 % noise, single precision). With
/// the selection no longer capped at four effects, each is named (or a family holding
/// it: a force's direction and location, a sensor's position and orientation can trade
/// at the few points a test has), nothing else, and χ²/ν ends in the noise band.
///
/// Measured (release, 2 shared cores at load ≈ 12): all six named (`elastic_mode`,
/// `force_direction`, `sensor_misorientation`, `sensor_position`, `force_gauge_mass`,
/// `channel_gain`, in that order), nothing else; χ²/ν 3201.4 → 0.982 in the band
/// 0.971–1.050; 186 s for the check.
#[test]
#[ignore = "study (186 s release on 2 shared cores): six concealed effects at once"]
fn six_concealed_effects_are_all_named() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let (g, frf) = refgen(&py, "tc2-six-effects", &[], 7, &nom);
    assert_explained(
        "six concealed effects",
        &nom,
        &g,
        &frf,
        &[
            "sensor_misorientation",
            "sensor_position",
            "channel_gain",
            "force_direction",
            "force_gauge_mass",
            "elastic_mode",
        ],
        &["force_location"],
    );
}

/// Impact testing as a tester does it (refgen `tc2-impact`, its time route: five
/// hammer impacts per excitation, 32 s records at 8 192 Hz, an exponential window
/// τ = 8 s on force and response, white force and response noise, H1 over the hits;
/// the physics exactly the spec's). The window makes the noise correlated from line to
/// line (γ₁ = 0.79): weighed as independent lines the check named the window and the
/// record's truncation, then stayed at χ²/ν ≈ 3 and kept accepting false effects (for
/// over ten minutes on this recording, the example's own seed; six in 418 s release on
/// seed 1 without force noise). Now the correlation is found and weighed (data-only
/// noise): the window and the truncation are named, nothing else — not the force
/// channel's noise either, which gives each excitation a relative error common to its
/// channels, a gain of a few 1e-5 below what a calibration resolves — and χ²/ν ends in
/// its band.
#[test]
fn impact_testing_with_an_exponential_window_names_the_window_and_the_record() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(401);
    let (g, frf) = refgen(&py, "tc2-impact", &[], 2, &nom);
    let r = checked_on_data_noise("impact testing", &nom, &g, &frf);
    let mut ids = named(&r);
    ids.sort();
    assert_eq!(
        ids,
        ["exponential_window", "record_truncation"],
        "{}",
        r.verdict
    );
    assert!(
        r.diagnostics.iter().any(|d| matches!(
            d.kind,
            rbprops_core::records::DiagnosticKind::CorrelatedNoise
                | rbprops_core::records::DiagnosticKind::UndeclaredWindow
        )),
        "{:?}",
        r.diagnostics
    );
    crate::common::assert_chi2_in_band("impact testing", &r);
    // The decay rate to 0.1 % (the record's sampling leaves a few standard errors,
    // ≈ 2e-5 each, between the time route's H1 and the analytic window).
    let window = r
        .accepted
        .iter()
        .find(|a| a.id == "exponential_window")
        .unwrap();
    let decay = &window.parameters[0];
    assert!((decay.value / 0.125 - 1.0).abs() < 1e-3, "{decay:?}");
}

/// Six concealed effects at once (issue 37), the generator's `tc2-six-effects` at 400
/// lines (sensor 2 misoriented ≈2°, sensor 3 displaced 5 mm, channel 1y gain +6 %,
/// force2's direction off 5°, a 50 g gauge mass under force3, an in-band elastic mode
/// at 10 Hz; 1 % noise, float32), noise from the data: the six are named, nothing else
/// (an ambiguity family only among them), and χ²/ν ends in the noise band.
/// Measured (release, 2 shared cores, load ≈ 6): the six named, χ²/ν 3335 → 1.014
/// (band 0.952–1.050), 120 s (178 s before the final re-test, at a higher load).
#[test]
fn six_concealed_effects_are_named_exactly() {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let (g, frf) = refgen(&py, "tc2-six-effects", &[], 7, &nom);
    let r = checked_on_data_noise("six effects", &nom, &g, &frf);
    assert_exactly(
        "six effects",
        &r,
        &[
            "sensor_misorientation",
            "sensor_position",
            "channel_gain",
            "force_direction",
            "force_gauge_mass",
            "elastic_mode",
        ],
    );
}

/// The six-effect combination on the dashpot set-up: anisotropic 3×3 dashpots at
/// the mounts (no modal damping), sensor 2 misoriented ≈3.5°, sensor 3 displaced 6 mm,
/// force2's direction off ≈4°, a 50 g gauge mass under force3 and an exponential window
/// τ = 8 s; 1 % noise, given. Exactly these are named (ambiguity only among them).
#[test]
fn dashpots_with_five_more_effects_are_named_exactly() {
    dashpots_named_exactly(
        "dashpots and five more",
        &[
            "sensor.2.misorientation_rad=[0.035,-0.04,0.02]",
            "sensor.3.position_error_m=[0.004,-0.005,0.0]",
            "excitation.force2.direction_error_rad=[0.0,0.03,0.07]",
            "excitation.force3.gauge_mass_kg=0.05",
            "window.tau_s=8.0",
        ],
        37,
        &[
            "nonproportional_damping",
            "sensor_misorientation",
            "sensor_position",
            "force_direction",
            "force_gauge_mass",
            "exponential_window",
        ],
    );
}

/// One excitation wrong four ways at once, on the dashpot set-up: force3's direction
/// off 3.9°, its hammer 11 mm across its line of action, a 78 g gauge under it and its
/// gauge's sensitivity 4.4 % low (the combination study's seed 5062, whose dashpots
/// differ); 1 % noise, given. The force-location refit used to move forces 1 and 2 by
/// 0.2–0.8 m (implausible, so the true item was rejected with them), and once that was
/// mended, to slide along force lines turned by a milliradian to its 1 m bound: ten
/// effects were named, five false. Exactly the five now.
#[test]
fn one_excitation_wrong_four_ways_is_named_exactly() {
    dashpots_named_exactly(
        "force3 four ways",
        &[
            "excitation.force3.direction_error_rad=[0.0565,0.039,-0.0096]",
            "excitation.force3.position_error_m=[0.0112,0.0004,-0.0011]",
            "excitation.force3.gauge_mass_kg=0.078",
            "excitation.force3.force_gauge_gain=0.956",
        ],
        5062,
        &[
            "nonproportional_damping",
            "force_direction",
            "force_location",
            "force_gauge_mass",
            "excitation_gain",
        ],
    );
}

/// A channel gain (sensor 1's y, −5.7 %) and force3 8 mm across its line, on the dashpot
/// set-up (the combination study's seed 5130, whose dashpots differ); 1 % noise, given.
/// The gain's common mode (every channel, which the mass absorbs) drifted to +34 % while
/// the location entered, the final re-test dropped the true gain as implausible and five
/// false effects filled its place; the re-test now judges the effects with their gauges
/// centred. Exactly the three.
#[test]
fn a_gain_drifted_along_its_gauge_is_not_dropped_as_implausible() {
    dashpots_named_exactly(
        "gain and location",
        &[
            "sensor.1.gains=[1.0,0.9426,1.0]",
            "excitation.force3.position_error_m=[0.0074,-0.0031,0.0056]",
        ],
        5130,
        &["nonproportional_damping", "channel_gain", "force_location"],
    );
}

/// Two gains and two position errors on the springs (the combination study's seed 5157,
/// the same recording): sensor 1's z gain +3.6 %, sensor 1 5.5 mm off, force2 15 mm off
/// and its gauge +3.8 %. An added mass at force2 explains a little more than either gain
/// and entered third; both gains were then vetoed by the held-out excitations and the
/// check ended at χ²/ν 1.86 with the mass claimed. The selection without it, run to its
/// end, names both gains and reaches the floor (docs/physics.md, M6f).
#[test]
fn a_compensating_effect_is_taken_back() {
    let Some((nom, g, frf)) = springs_study_recording(
        &[
            "sensor.1.gains=[1.0,1.0,1.0364596822132786]",
            "sensor.1.position_error_m=[0.0042032806426207615,-0.005550657367630677,-0.00011539906052715724]",
            "excitation.force2.position_error_m=[-0.006449965997932599,-0.003929506893910938,0.01272450659395475]",
            "excitation.force2.force_gauge_gain=1.0381023549326187",
        ],
        5157,
    ) else {
        return;
    };
    let r = checked_on_data_noise("taken back", &nom, &g, &frf);
    assert!(
        r.screening
            .iter()
            .any(|e| e.id == "added_mass" && e.decision.starts_with("taken back")),
        "the added mass was not taken back: {}",
        r.verdict
    );
    assert_exactly(
        "taken back",
        &r,
        &[
            "channel_gain",
            "sensor_position",
            "force_location",
            "excitation_gain",
        ],
    );
}

/// A force turned 3.4° (force3) and another struck 15 mm off its point (force2), seed
/// 7022 of the impact study, here as FRFs at 1 % noise. The direction enters first and
/// turns force2 by two milliradians to stand in for its offset; force2's location along
/// its own line is then a combination of its perpendicular offsets to one part in 10⁵.
/// Left free, it slid to its bound of a metre and the right two effects stalled at
/// χ²/ν 8.2 (band 0.95–1.05), force2's offset 3 mm short. Dropped as a near-gauge
/// without own signature (docs/physics.md, M5), the fit reaches the floor and force2's
/// perpendicular offsets agree with the truth within four standard errors.
#[test]
fn a_location_along_a_turned_line_does_not_slide() {
    let Some((nom, g, frf)) = springs_study_recording(
        &[
            "excitation.force3.direction_error_rad=[-0.00476818922718958,-0.05895724426342728,0.054963746140795106]",
            "excitation.force2.position_error_m=[-0.013321289068029138,0.0028643851501216214,0.006024770001355892]",
        ],
        7022,
    ) else {
        return;
    };
    let r = checked_on_data_noise("turned line", &nom, &g, &frf);
    assert_exactly("turned line", &r, &["force_direction", "force_location"]);
    assert_fitted_within(
        &r,
        "force_location",
        &[
            ("offsets_m.force2.x", -0.013321289068029138),
            ("offsets_m.force2.z", 0.006024770001355892),
        ],
    );
}

/// Five effects on the springs (the combination study's seed 5165, the same recording):
/// sensor 2's y gain −4.3 % and its misorientation (1.6°, 1.4°), force3's direction off
/// (3.2°, 2.2°, 3.3°), force1 11 mm off and force2's gauge +3.5 %. force_location used to
/// read force3 33 mm across its line, standing in for its direction error, and the final
/// re-test dropped it whole as implausible, force1's true 10 mm with it; a false
/// `{sensor_position|added_mass}` filled its place. Setting the implausible item back to
/// neutral (docs/physics.md, M6d) mended that; since force3's location along its turned
/// line is held as a near-gauge (M5), the location no longer stands in for the direction
/// at all: exactly the five, force3's offset within four standard errors of none and
/// force1's of the truth.
#[test]
fn a_location_does_not_stand_in_for_a_direction() {
    let Some((nom, g, frf)) = springs_study_recording(
        &[
            "sensor.2.gains=[1.0,0.9568199329620188,1.0]",
            "sensor.2.misorientation_rad=[0.02804056764818388,0.025189319168896808,-0.001366896476993097]",
            "excitation.force3.direction_error_rad=[-0.05532989004771708,0.03903265256523015,-0.05795203144919502]",
            "excitation.force1.position_error_m=[0.010029541509679968,-0.004730843108614538,0.0026109522420630182]",
            "excitation.force2.force_gauge_gain=1.0352772079249173",
        ],
        5165,
    ) else {
        return;
    };
    let r = checked_on_data_noise("location vs direction", &nom, &g, &frf);
    assert_exactly(
        "location vs direction",
        &r,
        &[
            "channel_gain",
            "sensor_misorientation",
            "force_direction",
            "force_location",
            "excitation_gain",
        ],
    );
    // force1 acts along −x and force3 along −z: their offsets across the line.
    assert_fitted_within(
        &r,
        "force_location",
        &[
            ("offsets_m.force1.y", -0.004730843108614538),
            ("offsets_m.force1.z", 0.0026109522420630182),
            ("offsets_m.force3.x", 0.0),
            ("offsets_m.force3.y", 0.0),
        ],
    );
}

/// Each named coordinate of accepted effect `id` within four standard errors of its
/// truth, with a standard error below 1 mm (or mrad): resolved, and where it should be.
fn assert_fitted_within(r: &ModelCheckReport, id: &str, truth: &[(&str, f64)]) {
    let e = r
        .accepted
        .iter()
        .find(|a| a.id == id)
        .unwrap_or_else(|| panic!("{id} not accepted"));
    for (name, t) in truth {
        let q = e
            .parameters
            .iter()
            .find(|q| q.name == *name)
            .unwrap_or_else(|| panic!("{id} has no coordinate {name}"));
        assert!(
            (q.value - t).abs() <= 4.0 * q.standard_error && q.standard_error < 1e-3,
            "{id} {name}: {} ± {} against {t}",
            q.value,
            q.standard_error
        );
    }
}

/// A recording of the generator's dashpot set-up with `sets` at 1 % noise (given), checked:
/// exactly `expected` named ([`assert_exactly`]).
fn dashpots_named_exactly(label: &str, sets: &[&str], seed: u64, expected: &[&str]) {
    let Some(py) = python(NUMPY_PYUFF) else {
        return;
    };
    let nom = nominal(400);
    let noise = format!("noise.relative={REL}");
    let sets: Vec<&str> = std::iter::once(noise.as_str())
        .chain(sets.iter().copied())
        .collect();
    let (g, frf) = refgen(&py, "tc2-dashpots", &sets, seed, &nom);
    let r = checked_on_data_noise(label, &nom, &g, &frf);
    assert_exactly(label, &r, expected);
}

/// Exactly `expected` named: each accepted or in an ambiguity family, every accepted
/// effect expected, every family one of an expected effect's ("one of A / B" names A
/// with its rival, not B); χ²/ν in the noise band.
fn assert_exactly(label: &str, r: &ModelCheckReport, expected: &[&str]) {
    let ids = named(r);
    for e in expected {
        assert!(
            ids.iter().any(|i| i == e),
            "{label}: {e} not named: {}",
            r.verdict
        );
    }
    let stray: Vec<&String> = r
        .accepted
        .iter()
        .map(|a| &a.id)
        .filter(|i| !expected.contains(&i.as_str()))
        .collect();
    assert!(
        stray.is_empty(),
        "{label}: false claims {stray:?}: {}",
        r.verdict
    );
    for f in &r.ambiguous {
        assert!(
            f.ids.iter().any(|i| expected.contains(&i.as_str())),
            "{label}: ambiguity family {:?} holds no concealed effect: {}",
            f.ids,
            r.verdict
        );
    }
    crate::common::assert_chi2_in_band(label, r);
}
