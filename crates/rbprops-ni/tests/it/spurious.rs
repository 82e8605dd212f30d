//! What `modal-fit` returns on noisy data: split poles, leakage poles, noise and elastic
//! poles. Per set-up at most six physical modes are kept, the true ones, each from the
//! right excitation, and every rejected estimate is reported with its reason.
use crate::common::*;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rbprops_core::records::{DiagnosticKind, Severity};
use rbprops_core::records::{ModalFitRecord, ModeEstimate};
use rbprops_core::{c64, RigidBasis, Vec6};
use rbprops_ni::{select_modes, SelectOptions, SelectionOutput};

fn hz() -> Vec<f64> {
    axis(0.1, 1.5, 0.0005)
}

/// Index in `rec` of excitation `ex`'s estimate of true mode `r` (0-based).
fn estimate_of(m: &Model, rec: &ModalFitRecord, ex: &str, r: usize) -> usize {
    let setup = &m.excitation(ex).setup;
    rec.modes
        .iter()
        .position(|e| e.excitation == ex && m.true_mode_near(setup, e.frequency_hz) == r)
        .unwrap_or_else(|| panic!("fixture: {ex} has no estimate of mode {}", r + 1))
}

/// Renumbers each excitation's estimates in ascending frequency, as modal-fit does.
fn renumber(rec: &mut ModalFitRecord) {
    rec.modes.sort_by(|a, b| {
        a.excitation
            .cmp(&b.excitation)
            .then(a.frequency_hz.total_cmp(&b.frequency_hz))
    });
    let mut n = 0;
    for i in 0..rec.modes.len() {
        n = if i > 0 && rec.modes[i - 1].excitation == rec.modes[i].excitation {
            n + 1
        } else {
            1
        };
        rec.modes[i].mode = n;
    }
}

/// A copy of `e` with residues `A · z`, frequency `f · ratio` and the given confidence.
fn pole(e: &ModeEstimate, z: c64, ratio: f64, confidence: f64) -> ModeEstimate {
    let mut p = e.clone();
    p.residues = e.residues.iter().map(|a| a * z).collect();
    p.frequency_hz *= ratio;
    p.confidence = confidence;
    p
}

/// Splits estimate `i` of `rec` into two poles 0.2 % apart whose complex residues
/// (phases ±1.06 rad) sum to the original, as a fit does with one resonance and too
/// many poles, plus a third weaker complex pole 0.3 % above. Returns the three new poles'
/// frequencies.
fn split(rec: &mut ModalFitRecord, i: usize) -> [f64; 3] {
    let e = rec.modes.remove(i);
    let parts = [
        pole(&e, c64::new(0.5, 0.9), 0.999, 0.3),
        pole(&e, c64::new(0.5, -0.9), 1.001, 0.25),
        pole(&e, c64::from_polar(0.4, 1.3), 1.003, 0.2),
    ];
    let f = [
        parts[0].frequency_hz,
        parts[1].frequency_hz,
        parts[2].frequency_hz,
    ];
    rec.modes.extend(parts);
    renumber(rec);
    f
}

fn select(m: &Model, frf: &rbprops_core::FrfSet, rec: &ModalFitRecord) -> SelectionOutput {
    select_modes(&m.geometry, frf, rec, &SelectOptions::default()).unwrap()
}

/// (mode, excitation, true mode nearest) of the selection in `setup`.
fn picks(m: &Model, out: &SelectionOutput, setup: &str) -> Vec<(usize, String, usize)> {
    out.record
        .selected
        .iter()
        .filter(|s| s.setup == setup)
        .map(|s| {
            (
                s.mode,
                s.excitation.clone(),
                m.true_mode_near(setup, s.frequency_hz) + 1,
            )
        })
        .collect()
}

fn noisy(seed: u64) -> EstimateSpec {
    EstimateSpec {
        residue_noise: 0.004,
        frequency_noise: 1e-3,
        seed,
        ..Default::default()
    }
}

/// Test-Case-I set-up A, mode 6 (θz) is excited by F0y ((fᵀφ)² = 0.0667) and F0x (0.0167).
/// F0y's estimate becomes a split pole with a third spurious pole: three poles within
/// 0.4 % with the same shape. Every seed of residue noise: six modes, the θz mode taken
/// from F0x's clean estimate, two of F0y's three poles rejected as parts of a split
/// pole, the third kept in the group but not eligible (confidence 0.3 < 0.5).
#[test]
fn split_pole_with_a_third_spurious_pole_gives_one_mode() {
    let m = test_case_one();
    let frf = frfs(&m, &hz());
    let clean = select(&m, &frf, &estimates(&m, EstimateSpec::default()));
    let expected = picks(&m, &clean, "A");
    assert_eq!(
        expected.iter().map(|p| p.1.as_str()).collect::<Vec<_>>(),
        ["F0x", "F0z", "F0z", "F0z", "F0y", "F0y"],
        "fixture"
    );
    assert!(m.participation("F0x", 5) > 0.01 && m.participation("F0y", 5) > 0.05);
    for seed in 1..=10 {
        let mut rec = estimates(&m, noisy(seed));
        let i = estimate_of(&m, &rec, "F0y", 5);
        let f = split(&mut rec, i);
        let out = select(&m, &frf, &rec);
        let got = picks(&m, &out, "A");
        let mut want = expected.clone();
        want[5].1 = "F0x".into();
        assert_eq!(got, want, "seed {seed}: {:#?}", out.record.diagnostics);
        assert_eq!(out.matches.iter().filter(|g| g.setup == "A").count(), 6);
        // Two of the three poles rejected, each with its reason.
        let rej: Vec<_> = out
            .rejected
            .iter()
            .filter(|r| r.excitation == "F0y")
            .collect();
        assert_eq!(rej.len(), 2, "seed {seed}: {rej:#?}");
        for r in &rej {
            assert!(f.contains(&r.frequency_hz));
            assert!(r.reason.contains("split pole"), "{}", r.reason);
        }
        assert!(out
            .record
            .diagnostics
            .iter()
            .any(|d| d.kind == DiagnosticKind::DuplicatePoles
                && d.severity == Severity::Note
                && d.message.contains("merged")));
        // The kept pole is the best of the three (confidence 0.3) and gives way to F0x.
        let g6 = out
            .matches
            .iter()
            .find(|g| g.setup == "A" && g.mode == 6)
            .unwrap();
        let row = g6.ranking.iter().find(|r| r.excitation == "F0y").unwrap();
        assert_eq!(row.confidence, Some(0.3));
        assert!(!row.eligible);
        assert!(row.reason.as_deref().unwrap().contains("confidence"));
        // No rejected estimate is also in a group.
        for r in &out.rejected {
            assert!(!out.matches.iter().any(|g| g
                .ranking
                .iter()
                .any(|x| x.excitation == r.excitation
                    && x.excitation_mode == Some(r.excitation_mode))));
        }
    }
}

/// When the split excitation is the only one that identifies the mode, its best pole is
/// still used (with its low confidence in the row), not lost.
#[test]
fn a_split_pole_is_used_when_no_other_excitation_has_the_mode() {
    let m = test_case_one();
    let frf = frfs(&m, &hz());
    let mut rec = estimates(&m, EstimateSpec::default());
    // Mode 5 of set-up A (y translation) is identified by F0y only.
    assert_eq!(
        rec.modes
            .iter()
            .filter(|e| e.setup == "A" && m.true_mode_near("A", e.frequency_hz) == 4)
            .count(),
        1,
        "fixture"
    );
    let i = estimate_of(&m, &rec, "F0y", 4);
    split(&mut rec, i);
    let out = select(&m, &frf, &rec);
    let got = picks(&m, &out, "A");
    assert_eq!(got.len(), 6);
    assert_eq!(got[4], (5, "F0y".to_string(), 5));
    let s = out
        .record
        .selected
        .iter()
        .find(|s| s.setup == "A" && s.mode == 5)
        .unwrap();
    // The kept pole is the 0.3-confidence one: the lowest-frequency pole of the split.
    let est = rec
        .modes
        .iter()
        .find(|e| e.excitation == "F0y" && e.mode == s.excitation_mode)
        .unwrap();
    assert_eq!(est.confidence, 0.3);
}

/// A leakage pole (demo-0001): F0x, which does not excite set-up A's mode 5, returns a pole
/// at mode 5's frequency carrying its mode 1's shape, with nearly imaginary residues.
/// It is rejected as a copy of mode 1, and F0y still gives mode 5.
#[test]
fn a_pole_with_a_neighbours_shape_is_rejected_as_leakage() {
    let m = test_case_one();
    let frf = frfs(&m, &hz());
    let clean = select(&m, &frf, &estimates(&m, EstimateSpec::default()));
    let expected = picks(&m, &clean, "A");
    assert!(m.participation("F0x", 4) < 1e-20, "fixture");
    for seed in 1..=10 {
        let mut rec = estimates(&m, noisy(seed));
        let e1 = rec.modes[estimate_of(&m, &rec, "F0x", 0)].clone();
        let f5 = m.modes_of("A")[4].frequency_hz;
        let mut leak = pole(&e1, c64::from_polar(0.3, 1.45), f5 / e1.frequency_hz, 0.2);
        leak.warnings.push("leakage".into());
        rec.modes.push(leak);
        renumber(&mut rec);
        let out = select(&m, &frf, &rec);
        assert_eq!(picks(&m, &out, "A"), expected, "seed {seed}");
        let rej: Vec<_> = out.rejected.iter().filter(|r| r.setup == "A").collect();
        assert_eq!(rej.len(), 1, "seed {seed}: {rej:#?}");
        assert_eq!(rej[0].excitation, "F0x");
        assert!((rej[0].frequency_hz - f5).abs() < 1e-12);
        assert!(
            rej[0].reason.contains("copy (leakage)"),
            "{}",
            rej[0].reason
        );
        assert!(out
            .record
            .diagnostics
            .iter()
            .any(|d| d.kind == DiagnosticKind::ModeRejected && d.message.contains("leakage")));
    }
}

/// Residues `(Sφ + d)(fᵀφ)` of a pole that is not rigid-body motion: `d` is orthogonal to
/// every rigid motion at the channels, with `‖d‖ = r/√(1−r²) ‖Sφ‖` so that the rigid
/// residual is exactly `r`.
fn non_rigid_estimate(
    m: &Model,
    ex: &str,
    phi: &Vec6,
    r: f64,
    f_hz: f64,
    rng: &mut ChaCha8Rng,
) -> ModeEstimate {
    let g = &m.geometry;
    let basis = RigidBasis::new(g.channel_matrix()).unwrap();
    let s_phi: Vec<f64> = g.channels.iter().map(|c| (c.row() * phi)[0]).collect();
    let raw: Vec<f64> = (0..s_phi.len()).map(|_| normal(rng)).collect();
    let d = basis.fit(&raw).unwrap().residual;
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let scale = r / (1.0 - r * r).sqrt() * norm(&s_phi) / norm(&d);
    let c = m.excitation(ex).column().dot(phi);
    let k = g.excitation_index(ex).unwrap();
    let residues: Vec<c64> = s_phi
        .iter()
        .zip(&d)
        .map(|(a, b)| c64::new((a + scale * b) * c, 0.0))
        .collect();
    ModeEstimate {
        excitation: ex.into(),
        setup: g.excitations[k].setup.clone(),
        mode: 0,
        frequency_hz: f_hz,
        frequency_std_hz: 1e-4 * f_hz,
        damping_ratio: ZETA,
        damping_std: 0.0,
        residue_std: vec![
            1e-3 * norm(&residues.iter().map(|z| z.re).collect::<Vec<_>>());
            residues.len()
        ],
        residues,
        confidence: 1.0,
        mpc: 1.0,
        weak: false,
        warnings: Vec::new(),
    }
}

/// A shape that is a mix of all six true modes of `setup` (MAC < 0.8 with each).
fn mixed_shape(m: &Model, setup: &str) -> Vec6 {
    let modes = m.modes_of(setup);
    let phi: Vec6 = modes.iter().map(|x| x.shape).sum::<Vec6>() / 6f64.sqrt();
    for t in modes {
        assert!(mac_s(m, &phi, &t.shape) < 0.8, "fixture");
    }
    phi
}

/// Set-up B: an elastic-like pole between modes 3 and 4, identified cleanly
/// (confidence 1, real residues, well above the noise) by both F1x and F2y, so that it
/// looks like a well-supported seventh mode; its shape is 30 % away from rigid motion.
/// It is rejected with its rigid residual in the message; the six true modes are selected
/// from the same excitations as without it, every seed.
#[test]
fn seven_supported_looking_groups_one_non_rigid() {
    let m = test_case_one();
    let frf = frfs(&m, &hz());
    let clean = select(&m, &frf, &estimates(&m, EstimateSpec::default()));
    let expected = picks(&m, &clean, "B");
    let modes = m.modes_of("B");
    let f_el = (modes[2].frequency_hz * modes[3].frequency_hz).sqrt();
    assert!(
        modes[3].frequency_hz / modes[2].frequency_hz > 1.12,
        "fixture"
    );
    let phi = mixed_shape(&m, "B");
    for seed in 1..=10 {
        let mut rec = estimates(&m, noisy(seed));
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for ex in ["F1x", "F2y"] {
            rec.modes
                .push(non_rigid_estimate(&m, ex, &phi, 0.3, f_el, &mut rng));
        }
        renumber(&mut rec);
        let out = select(&m, &frf, &rec);
        assert_eq!(picks(&m, &out, "B"), expected, "seed {seed}");
        assert_eq!(out.matches.iter().filter(|g| g.setup == "B").count(), 6);
        let rej: Vec<_> = out.rejected.iter().filter(|r| r.setup == "B").collect();
        assert_eq!(rej.len(), 2, "seed {seed}: {rej:#?}");
        for r in &rej {
            assert!((r.frequency_hz - f_el).abs() < 1e-12);
            assert!(r.reason.contains("least evidence"), "{}", r.reason);
        }
        let w = out
            .record
            .diagnostics
            .iter()
            .find(|d| {
                d.kind == DiagnosticKind::ModeRejected
                    && d.subject
                        .frequencies_hz
                        .first()
                        .is_some_and(|f| (f - f_el).abs() < 1e-12)
            })
            .expect("a diagnostic names the rejected mode");
        assert!(w.message.contains("rigid residual 30.0%"), "{w:?}");
        assert!(
            !out.record
                .diagnostics
                .iter()
                .any(|d| d.kind == DiagnosticKind::UndecidedModes),
            "seed {seed}: {:#?}",
            out.record.diagnostics
        );
    }
}

/// A seventh pole that looks exactly like a clean rigid-body mode of one excitation has as
/// much support as a true mode seen by one excitation only: six modes are still kept, and
/// a warning says that the evidence does not decide.
#[test]
fn undecidable_case_is_reported() {
    let m = test_case_one();
    let frf = frfs(&m, &hz());
    let modes = m.modes_of("B");
    let f_x = (modes[2].frequency_hz * modes[3].frequency_hz).sqrt();
    let phi = mixed_shape(&m, "B");
    let mut rec = estimates(&m, EstimateSpec::default());
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // F1x barely drives mode 4 (flagged weak): mode 4 rests on F2y alone, support ≈ 1.
    rec.modes
        .push(non_rigid_estimate(&m, "F2y", &phi, 0.0, f_x, &mut rng));
    renumber(&mut rec);
    let out = select(&m, &frf, &rec);
    assert_eq!(out.matches.iter().filter(|g| g.setup == "B").count(), 6);
    assert_eq!(picks(&m, &out, "B").len(), 6);
    assert!(
        out.record
            .diagnostics
            .iter()
            .any(|d| d.kind == DiagnosticKind::UndecidedModes
                && d.severity == Severity::Warning
                && d.message.contains("does not clearly decide")),
        "{:#?}",
        out.record.diagnostics
    );
}

/// A group supported only by weak estimates (demo-0003): when it makes a seventh, it is
/// the one rejected, with "no excitation identifies it reliably".
#[test]
fn a_weak_only_group_is_rejected_first() {
    let m = test_case_one();
    let frf = frfs(&m, &hz());
    let clean = select(&m, &frf, &estimates(&m, EstimateSpec::default()));
    let expected = picks(&m, &clean, "B");
    let modes = m.modes_of("B");
    let f_x = (modes[2].frequency_hz * modes[3].frequency_hz).sqrt();
    let phi = mixed_shape(&m, "B");
    let mut rec = estimates(&m, EstimateSpec::default());
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let mut w = non_rigid_estimate(&m, "F1x", &phi, 0.05, f_x, &mut rng);
    w.weak = true;
    rec.modes.push(w);
    renumber(&mut rec);
    let out = select(&m, &frf, &rec);
    assert_eq!(picks(&m, &out, "B"), expected);
    let rej: Vec<_> = out.rejected.iter().filter(|r| r.setup == "B").collect();
    assert_eq!(rej.len(), 1);
    assert!(
        rej[0]
            .reason
            .contains("no excitation identifies it reliably"),
        "{}",
        rej[0].reason
    );
}
