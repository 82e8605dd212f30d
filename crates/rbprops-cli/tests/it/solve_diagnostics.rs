//! rb-solve's run-level diagnostics (a missing mode, a failed estimator, …) are stored in
//! the run record, read back from MCAP and CSV, and gathered by the campaign and report
//! reader; a later solve with nothing to say removes them.

use rbprops_cli::stages;
use rbprops_core::records::{DiagnosticKind, MissingMode, SelectionRecord, Severity};
use rbprops_formats::{topics, RunRecord};

/// The demo campaign through ni-select, with one mode the selection says is missing (as
/// when no excitation drove it); the modes it did select are all there.
fn selected_with_a_missing_mode() -> RunRecord {
    let spec = rbprops_sim::examples::example("demo").unwrap();
    let (mut rec, _) = stages::simulate(spec, "demo", Some(3)).unwrap();
    stages::modal_fit(&mut rec, &Default::default(), "test").unwrap();
    stages::ni_select(&mut rec, &Default::default(), "test").unwrap();
    let mut sel: SelectionRecord = rec.get_one(topics::SELECTION).unwrap().unwrap();
    let setup = sel.selected[0].setup.clone();
    sel.missing.push(MissingMode {
        setup,
        mode: 7,
        frequency_hz: 9.5,
        tried: vec!["every excitation".into()],
        reason: "no excitation drove it above the noise".into(),
    });
    rec.set(topics::SELECTION, &[sel]);
    rec
}

fn missing_mode_diagnostics(rec: &RunRecord) -> usize {
    rbprops_cli::warnings::from_record(rec)
        .unwrap()
        .iter()
        .filter(|d| {
            d.stage == "rb-solve"
                && d.kind == DiagnosticKind::ModeMissing
                && d.severity == Severity::ChangesAnswer
                && d.message.contains("no excitation drove it above the noise")
        })
        .count()
}

#[test]
fn the_solves_diagnostics_travel_with_the_record() {
    let mut rec = selected_with_a_missing_mode();
    let out = stages::rb_solve(&mut rec, &Default::default(), false, "test").unwrap();
    assert!(
        out.diagnostics
            .iter()
            .any(|d| d.kind == DiagnosticKind::ModeMissing),
        "{:?}",
        out.diagnostics
    );
    assert_eq!(
        rec.get::<rbprops_core::records::Diagnostic>(topics::SOLVE_DIAGNOSTICS)
            .unwrap(),
        out.diagnostics
    );
    assert_eq!(missing_mode_diagnostics(&rec), 1);
    let dir = tempfile::tempdir().unwrap();
    for name in ["run.mcap", "run_csv"] {
        let path = dir.path().join(name);
        rbprops_formats::write_path(&rec, &path).unwrap();
        let back = rbprops_formats::read_path(&path).unwrap();
        assert_eq!(missing_mode_diagnostics(&back), 1, "{name}");
    }
    // The same record solved again without the missing mode: the topic goes.
    let mut sel: SelectionRecord = rec.get_one(topics::SELECTION).unwrap().unwrap();
    sel.missing.clear();
    rec.set(topics::SELECTION, &[sel]);
    let out = stages::rb_solve(&mut rec, &Default::default(), false, "test").unwrap();
    assert_eq!(missing_mode_diagnostics(&rec), 0);
    assert_eq!(
        rec.topic(topics::SOLVE_DIAGNOSTICS).is_some(),
        !out.diagnostics.is_empty()
    );
}
