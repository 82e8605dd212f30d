//! The diagnostics every stage emits, gathered per stage and printed on stderr: the ones
//! that matter to the answer (severity [`Severity::Warning`] or
//! [`Severity::ChangesAnswer`]) always, one line each; the notes (correctly handled
//! conditions) as one summary line per stage naming their kinds, listed with `-v`. The
//! HTML report groups the same diagnostics by stage and kind, each kind with its own
//! sentence ([`DiagnosticKind::sentence`]).
//!
//! Nothing here reads a diagnostic's text: how much it matters is its severity, what it
//! means is its kind, both set where the stage raised it. Messages of files written
//! before diagnostics were typed read as [`DiagnosticKind::Text`] (shown, as their weight
//! is not known).

pub use rbprops_core::records::{Diagnostic, DiagnosticKind, DiagnosticSubject, Severity};
use rbprops_formats::{topics, RunRecord};

/// Whether a diagnostic is printed without `-v`: whatever may change the answer.
pub fn shown_by_default(d: &Diagnostic) -> bool {
    d.severity != Severity::Note
}

/// The word a printed line carries for a severity.
pub fn severity_label(s: Severity) -> &'static str {
    match s {
        Severity::Note => "note",
        Severity::Warning => "warning",
        Severity::ChangesAnswer => "changes the answer",
    }
}

/// A note of `stage` whose only source is one kind of text (the simulator's notes, the
/// UFF reader's, a modal fit's per-excitation details): typed by where it comes from.
pub fn note_of(
    stage: &str,
    kind: DiagnosticKind,
    subject: DiagnosticSubject,
    text: &str,
) -> Diagnostic {
    Diagnostic::new(stage, kind, Severity::Note, subject, text)
}

/// Every diagnostic a run record carries, in pipeline order: modal-fit, ni-select, rb-solve
/// (the solve's, then per estimate), model-check. The same diagnostic on several estimates is kept once.
/// Records written before diagnostics were typed give their strings as
/// [`DiagnosticKind::Text`], stage filled in.
pub fn from_record(rec: &RunRecord) -> anyhow::Result<Vec<Diagnostic>> {
    use rbprops_core::records::{InertiaEstimate, ModalFitRecord, SelectionRecord};
    let mut out = Collector::default();
    if let Some(m) = rec.get_one::<ModalFitRecord>(topics::MODAL_FIT)? {
        if m.diagnostics.is_empty() {
            // Written before modal-fit's diagnostics were typed: its texts.
            let texts = m.excitations.iter().flat_map(|e| &e.warnings);
            for t in texts.chain(m.modes.iter().flat_map(|m| &m.warnings)) {
                out.add_from("modal-fit", Diagnostic::from_text(t.clone()));
            }
        } else {
            out.extend(m.diagnostics.iter().cloned());
        }
    }
    if let Some(s) = rec.get_one::<SelectionRecord>(topics::SELECTION)? {
        for d in s.diagnostics {
            out.add_from("ni-select", d);
        }
    }
    for d in rec.get::<Diagnostic>(topics::SOLVE_DIAGNOSTICS)? {
        out.add_from("rb-solve", d);
    }
    for e in rec.get::<InertiaEstimate>(topics::ESTIMATES)? {
        for d in e.diagnostics {
            out.add_from("rb-solve", d);
        }
    }
    // Read as plain JSON: a report with a non-finite statistic (written as null) does
    // not decode as `ModelCheckReport`, and its diagnostics must still be listed.
    if let Some(c) = rec.get_one::<serde_json::Value>(topics::MODEL_CHECK)? {
        let list = c.get("diagnostics").or_else(|| c.get("warnings"));
        if let Some(list) = list {
            let ds = rbprops_core::records::diagnostics_or_texts(list)
                .map_err(|e| anyhow::anyhow!("{}: diagnostics: {e}", topics::MODEL_CHECK))?;
            for d in ds {
                out.add_from("model-check", d);
            }
        }
    }
    Ok(out.items)
}

/// Diagnostics gathered in order, each once.
#[derive(Debug, Clone, Default)]
pub struct Collector {
    /// The diagnostics, in the order they were added.
    pub items: Vec<Diagnostic>,
}

impl Collector {
    /// Adds a diagnostic unless the same one is there already.
    pub fn add(&mut self, d: Diagnostic) {
        if !self.items.contains(&d) {
            self.items.push(d);
        }
    }

    /// Adds a diagnostic read from `stage`'s record: an older file's text has no stage.
    pub fn add_from(&mut self, stage: &str, mut d: Diagnostic) {
        if d.stage.is_empty() {
            d.stage = stage.into();
        }
        self.add(d);
    }

    /// Adds every diagnostic, each once.
    pub fn extend(&mut self, ds: impl IntoIterator<Item = Diagnostic>) {
        for d in ds {
            self.add(d);
        }
    }

    /// The stages in order of first appearance.
    fn stages(&self) -> Vec<&str> {
        let mut stages: Vec<&str> = Vec::new();
        for d in &self.items {
            if !stages.contains(&d.stage.as_str()) {
                stages.push(&d.stage);
            }
        }
        stages
    }

    /// The stderr lines, stage by stage, grouped by kind (kinds in order of first
    /// appearance): with `verbose`, every diagnostic; otherwise the ones that may change
    /// the answer and, per stage with notes, one summary line naming their kinds.
    pub fn lines(&self, verbose: bool) -> Vec<String> {
        let mut lines = Vec::new();
        for s in self.stages() {
            let of: Vec<&Diagnostic> = grouped_by_kind(self.items.iter().filter(|d| d.stage == s));
            let shown: Vec<&&Diagnostic> = of
                .iter()
                .filter(|d| verbose || shown_by_default(d))
                .collect();
            for d in &shown {
                lines.push(format!("{s}: {}: {}", severity_label(d.severity), d.line()));
            }
            let hidden: Vec<&&Diagnostic> = of
                .iter()
                .filter(|d| !verbose && !shown_by_default(d))
                .collect();
            if hidden.is_empty() {
                continue;
            }
            // Only notes are ever hidden: say so, so that a clean run does not read as one
            // with warnings; named by kind.
            let mut kinds: Vec<String> = Vec::new();
            for d in &hidden {
                let k = d.kind.as_str().replace('_', " ");
                if !kinds.contains(&k) {
                    kinds.push(k);
                }
            }
            let n = hidden.len();
            lines.push(format!(
                "{s}: {n} note{} ({}) on how the answer was reached{}; run with -v to list them",
                if n == 1 { "" } else { "s" },
                kinds.join(", "),
                match shown.len() {
                    0 => String::new(),
                    1 => " (1 warning above)".into(),
                    k => format!(" ({k} warnings above)"),
                }
            ));
        }
        lines
    }

    /// Prints [`Collector::lines`] on stderr.
    pub fn print(&self, verbose: bool) {
        for l in self.lines(verbose) {
            crate::say!("{l}");
        }
    }
}

/// The diagnostics ordered by kind (kinds in order of first appearance), each kind's in
/// their original order.
pub fn grouped_by_kind<'a>(ds: impl IntoIterator<Item = &'a Diagnostic>) -> Vec<&'a Diagnostic> {
    let ds: Vec<&Diagnostic> = ds.into_iter().collect();
    let mut kinds: Vec<DiagnosticKind> = Vec::new();
    for d in &ds {
        if !kinds.contains(&d.kind) {
            kinds.push(d.kind);
        }
    }
    kinds
        .into_iter()
        .flat_map(|k| ds.iter().copied().filter(move |d| d.kind == k))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn d(stage: &str, kind: DiagnosticKind, severity: Severity, message: &str) -> Diagnostic {
        Diagnostic::new(
            stage,
            kind,
            severity,
            DiagnosticSubject::setup("A"),
            message,
        )
    }

    /// Without -v: the warnings, then one summary line per stage naming its notes' kinds;
    /// a repeated diagnostic once; with -v every one, grouped by kind.
    #[test]
    fn default_output_is_one_line_per_stage_plus_the_warnings() {
        let mut c = Collector::default();
        let pole = d(
            "modal-fit",
            DiagnosticKind::PoleSearch,
            Severity::Note,
            "pole dropped",
        );
        c.add(pole.clone());
        c.add(d(
            "modal-fit",
            DiagnosticKind::WeakModes,
            Severity::Note,
            "weak",
        ));
        c.add(pole);
        c.add(d(
            "modal-fit",
            DiagnosticKind::PoleSearch,
            Severity::Note,
            "band",
        ));
        c.add(d(
            "rb-solve",
            DiagnosticKind::IllConditioned,
            Severity::Warning,
            "Φ0 is poorly conditioned (cond = 1e9)",
        ));
        c.add(d(
            "rb-solve",
            DiagnosticKind::ModeLeftOut,
            Severity::ChangesAnswer,
            "mode 3 left out",
        ));
        assert_eq!(
            c.lines(false),
            vec![
                "modal-fit: 3 notes (pole search, weak modes) on how the answer was reached; run with -v to list them",
                "rb-solve: warning: set-up A: Φ0 is poorly conditioned (cond = 1e9)",
                "rb-solve: changes the answer: set-up A: mode 3 left out",
            ]
        );
        assert_eq!(
            c.lines(true)[..3],
            [
                "modal-fit: note: set-up A: pole dropped",
                "modal-fit: note: set-up A: band",
                "modal-fit: note: set-up A: weak",
            ]
        );
        assert!(Collector::default().lines(false).is_empty());
    }

    /// How much a diagnostic matters is its severity, whatever its text says: a note whose
    /// text holds alarming words stays a note, a warning whose text holds none is printed.
    #[test]
    fn diagnostics_are_classified_by_severity_not_text() {
        let mut c = Collector::default();
        c.add(d(
            "modal-fit",
            DiagnosticKind::RepeatedRoot,
            Severity::Note,
            "the old fit failed and is missing; cannot be separated; inconsistent",
        ));
        c.add(d(
            "modal-fit",
            DiagnosticKind::FitErrorAboveNoise,
            Severity::Warning,
            "median fit error 1.1",
        ));
        assert_eq!(
            c.lines(false),
            vec![
                "modal-fit: warning: set-up A: median fit error 1.1",
                "modal-fit: 1 note (repeated root) on how the answer was reached (1 warning above); run with -v to list them",
            ]
        );
    }

    /// An older record's strings read as shown `text` diagnostics of their stage.
    #[test]
    fn old_records_read_as_text_diagnostics() {
        use rbprops_core::records::SelectionRecord;
        let mut rec = RunRecord::default();
        let sel: SelectionRecord =
            serde_json::from_str(r#"{"selected":[],"missing":[],"warnings":["w1","w1","w2"]}"#)
                .unwrap();
        rec.set(topics::SELECTION, &[sel]);
        let ds = from_record(&rec).unwrap();
        assert_eq!(ds.len(), 2);
        assert!(ds.iter().all(|d| d.stage == "ni-select"
            && d.kind == DiagnosticKind::Text
            && shown_by_default(d)));
    }
}
