//! The warning collector every stage uses: warnings are gathered per stage, classified,
//! explained in one sentence, and printed on stderr as one summary line per stage plus
//! the warnings that change the answer (all of them with `-v`). The HTML report groups
//! the same warnings by stage with the same explanations.
//!
//! A warning *changes the answer* when the numbers a stage returns would be different
//! (or missing) without the condition it reports: a rigid-body mode missing or rejected,
//! rigid-body data inconsistent with the geometry, an ill-conditioned solve, a
//! non-physical inertia tensor, a failed uncertainty computation, a dead channel, a
//! digest mismatch. Everything else (a pole dropped by the order test, the band the
//! poles were estimated on, a rotation of complex residues) is a note on how the answer
//! was reached: counted, listed with `-v`.

use rbprops_core::records::{Diagnostic, DiagnosticKind, Severity};
use rbprops_formats::{topics, RunRecord};

/// How much a warning matters.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize, serde::Deserialize,
)]
#[serde(rename_all = "snake_case")]
pub enum Class {
    /// The result is different, incomplete or unreliable because of it: always printed.
    ChangesAnswer,
    /// How the result was reached: counted, listed with `-v`.
    Note,
}

/// One warning of one stage.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct StageWarning {
    /// The stage that raised it (`modal-fit`, `ni-select`, `rb-solve`, `model-check`, …).
    pub stage: String,
    /// The warning's text as the stage wrote it.
    pub text: String,
    /// How much it matters.
    pub class: Class,
    /// The kind of a typed diagnostic (`None`: a text warning, classified by [`explain`]).
    pub kind: Option<DiagnosticKind>,
}

impl StageWarning {
    /// A warning, classified by its text ([`classify`]).
    pub fn new(stage: &str, text: impl Into<String>) -> Self {
        let text = text.into();
        StageWarning {
            stage: stage.into(),
            class: classify(&text),
            text,
            kind: None,
        }
    }

    /// A typed diagnostic: classified by its severity (a note is a [`Class::Note`], a
    /// warning or a changed answer is printed), explained by its kind, never by its text.
    pub fn from_diagnostic(d: &Diagnostic) -> Self {
        StageWarning {
            stage: d.stage.clone(),
            text: d.line(),
            class: match d.severity {
                Severity::Note => Class::Note,
                Severity::Warning | Severity::ChangesAnswer => Class::ChangesAnswer,
            },
            kind: Some(d.kind),
        }
    }

    /// A note whatever its text says (e.g. `frf-sim`'s notes on the simulation).
    pub fn note(stage: &str, text: impl Into<String>) -> Self {
        StageWarning {
            class: Class::Note,
            ..StageWarning::new(stage, text)
        }
    }

    /// How much it matters ([`Class::ChangesAnswer`] or [`Class::Note`]).
    pub fn class(&self) -> Class {
        self.class
    }

    /// One sentence on what the warning means for the result.
    pub fn explanation(&self) -> &'static str {
        match self.kind {
            Some(k) => k.sentence(),
            None => explain(&self.text).1,
        }
    }
}

/// Phrases that mark a warning as changing the answer, with the sentence that explains
/// it to a test engineer. Matched case-insensitively, first match wins.
const RULES: &[(&[&str], Class, &str)] = &[
    (
        &["correlated from line to line"],
        Class::ChangesAnswer,
        "The FRFs' noise is shared by neighbouring lines (a window on the time histories, as in impact testing): the model check weighs it conservatively when it is an exponential window's, and otherwise its claims are not calibrated.",
    ),
    (
        &["is missing", "of the six rigid-body modes", "no identified modes", "not excited above the noise"],
        Class::ChangesAnswer,
        "A rigid-body mode was not found, so the estimate rests on fewer modes than the method needs and some properties may be unobservable.",
    ),
    (
        &["candidate modes for six rigid-body modes"],
        Class::Note,
        "More candidate modes than rigid-body modes were found; the one with the least evidence (a spurious or weakly excited pole) was set aside and the six kept.",
    ),
    (
        &["rejected"],
        Class::ChangesAnswer,
        "A mode or band was refused as not rigid-body-like; the estimate is computed without it.",
    ),
    (
        &["rigid-body consistent", "inconsistent", "suspect"],
        Class::ChangesAnswer,
        "The identified modes do not move as one rigid body on the given geometry: a sensor position, direction or calibration is probably wrong.",
    ),
    (
        &["physically", "non-physical", "not positive", "triangle inequality"],
        Class::ChangesAnswer,
        "The inertia tensor violates a physical bound (a negative mass or moment, or the triangle inequality): do not use these numbers.",
    ),
    (
        &["poorly conditioned", "nearly singular", "singular information", "not all identifiable", "cannot be separated"],
        Class::ChangesAnswer,
        "The equations are ill-conditioned: small errors in the data move the result a lot, so its uncertainty is larger than the noise alone suggests.",
    ),
    (
        &["identically zero", "the mode is left out", "dead channel"],
        Class::ChangesAnswer,
        "A channel or mode carried no usable data and was left out of the computation.",
    ),
    (
        &["failed", "standard errors are zero", "taken as zero", "too small"],
        Class::ChangesAnswer,
        "An uncertainty computation failed in part: the reported intervals may be too narrow.",
    ),
    (
        &["does not match the digest", "was changed after writing"],
        Class::ChangesAnswer,
        "The input was edited after it was written: the results may not be those of the original data.",
    ),
    (
        &["0 hz line"],
        Class::Note,
        "The 0 Hz line carries no dynamic information (and is zero under AC coupling); it is left out of the fit.",
    ),
    (
        &["model-order test", "residual test", "refinement", "computational"],
        Class::Note,
        "The pole selection adjusted the model order (a spurious pole dropped, a close pair split, a weak mode added); the reported modes already reflect it.",
    ),
    (
        &["poles estimated on", "shapes on the whole band", "residues on the whole band"],
        Class::Note,
        "The poles were fitted on the part of the band that holds the modes; shapes and residues use the whole band.",
    ),
    (
        &["complex residues", "rotated"],
        Class::Note,
        "Complex modal constants were rotated onto the real line, as the rigid-body equations need real mode shapes.",
    ),
    (
        &["away from rigid-body motion"],
        Class::Note,
        "A mode shape deviates from exact rigid motion by the amount stated; small values are the noise of the fit.",
    ),
    (
        &["repeated root", "one root of multiplicity"],
        Class::Note,
        "Two modes share one frequency; their shapes were separated by reciprocity.",
    ),
    (
        &["mass-line", "mass line"],
        Class::Note,
        "The mass line's band and its truncation bias, as used for the mass estimate.",
    ),
    (
        &["weak"],
        Class::Note,
        "An excitation barely drives this mode; another excitation's estimate of it is preferred.",
    ),
];

const GENERIC: &str =
    "A condition the stage noticed while computing; the numbers were produced regardless.";

/// The class and one-sentence explanation of a warning text.
pub fn explain(text: &str) -> (Class, &'static str) {
    let t = text.to_lowercase();
    RULES
        .iter()
        .find(|(phrases, _, _)| phrases.iter().any(|p| t.contains(p)))
        .map(|(_, c, e)| (*c, *e))
        .unwrap_or((Class::Note, GENERIC))
}

/// The class of a warning text (see the module documentation).
pub fn classify(text: &str) -> Class {
    explain(text).0
}

/// Every warning a run record carries, in pipeline order: modal-fit (per excitation and
/// per mode), ni-select, rb-solve (per estimate), model-check. Duplicates within a stage
/// (the same text on several estimates) are kept once.
pub fn from_record(rec: &RunRecord) -> anyhow::Result<Vec<StageWarning>> {
    use rbprops_core::records::{InertiaEstimate, ModalFitRecord, SelectionRecord};
    let mut out = Collector::default();
    if let Some(m) = rec.get_one::<ModalFitRecord>(topics::MODAL_FIT)? {
        if m.diagnostics.is_empty() {
            // Written before modal-fit's diagnostics were typed: its texts, classified.
            for e in &m.excitations {
                out.extend("modal-fit", &e.warnings);
            }
            for mode in &m.modes {
                out.extend("modal-fit", &mode.warnings);
            }
        } else {
            for d in &m.diagnostics {
                out.add(StageWarning::from_diagnostic(d));
            }
        }
    }
    if let Some(s) = rec.get_one::<SelectionRecord>(topics::SELECTION)? {
        out.extend("ni-select", &s.warnings);
    }
    for e in rec.get::<InertiaEstimate>(topics::ESTIMATES)? {
        out.extend("rb-solve", &e.warnings);
    }
    // Read as plain JSON: a report with a non-finite statistic (written as null) does
    // not decode as `ModelCheckReport`, and its warnings must still be listed.
    if let Some(c) = rec.get_one::<serde_json::Value>(topics::MODEL_CHECK)? {
        for w in c["warnings"].as_array().into_iter().flatten() {
            if let Some(t) = w.as_str() {
                out.push("model-check", t);
            }
        }
    }
    Ok(out.items)
}

/// Warnings gathered in order, each text once per stage.
#[derive(Debug, Clone, Default)]
pub struct Collector {
    /// The warnings, in the order they were added.
    pub items: Vec<StageWarning>,
}

impl Collector {
    /// Adds a warning of `stage`, classified by its text.
    pub fn push(&mut self, stage: &str, text: impl Into<String>) {
        self.add(StageWarning::new(stage, text));
    }

    /// Adds a warning unless the same text of the same stage is there already.
    pub fn add(&mut self, w: StageWarning) {
        if !self.items.contains(&w) {
            self.items.push(w);
        }
    }

    /// Adds every text of `stage`, each once.
    pub fn extend<'a>(&mut self, stage: &str, texts: impl IntoIterator<Item = &'a String>) {
        for t in texts {
            self.push(stage, t.clone());
        }
    }

    /// The stderr lines: with `verbose`, every warning; otherwise the warnings that
    /// change the answer and, per stage with warnings, one summary line.
    pub fn lines(&self, verbose: bool) -> Vec<String> {
        let mut stages: Vec<&str> = Vec::new();
        for w in &self.items {
            if !stages.contains(&w.stage.as_str()) {
                stages.push(&w.stage);
            }
        }
        let mut lines = Vec::new();
        for s in stages {
            let of: Vec<&StageWarning> = self.items.iter().filter(|w| w.stage == s).collect();
            let shown: Vec<&&StageWarning> = of
                .iter()
                .filter(|w| verbose || w.class() == Class::ChangesAnswer)
                .collect();
            for w in &shown {
                let kind = match w.class {
                    Class::ChangesAnswer => "warning",
                    Class::Note => "note",
                };
                lines.push(format!("{s}: {kind}: {}", w.text));
            }
            let hidden = of.len() - shown.len();
            if hidden > 0 {
                // Only notes are ever hidden: say so, so that a clean run does not read as
                // one with warnings. Typed notes are named by kind.
                let mut kinds: Vec<String> = Vec::new();
                for w in of.iter().filter(|w| !verbose && w.class() == Class::Note) {
                    if let Some(k) = w.kind {
                        let k = k.as_str().replace('_', " ");
                        if !kinds.contains(&k) {
                            kinds.push(k);
                        }
                    }
                }
                lines.push(format!(
                    "{s}: {hidden} note{}{} on how the answer was reached{}; run with -v to list them",
                    if hidden == 1 { "" } else { "s" },
                    if kinds.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", kinds.join(", "))
                    },
                    if shown.is_empty() {
                        String::new()
                    } else {
                        format!(
                            " ({} warning{} above)",
                            shown.len(),
                            if shown.len() == 1 { "" } else { "s" }
                        )
                    }
                ));
            }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn classes_follow_the_definition() {
        for t in [
            "set-up 'a' mode 3 (1.2345 Hz) is missing: no excitation drives it",
            "set-up 'a': only 5 of the six rigid-body modes were identified by any excitation",
            "set-up 'a': rejected the mode at 9.0000 Hz: elastic; its evidence: x",
            "Φ0 is poorly conditioned (cond = 1.0e9): the estimate is sensitive to shape errors",
            "uncertainty propagation failed (x); standard errors are reported as zero",
            "the noise is correlated from line to line (lag-1 excess 0.59 of the local polynomial residual, 51 SE over 7396 windows), as a window on the time histories makes it: an exponential window's correlation fits it",
        ] {
            assert_eq!(classify(t), Class::ChangesAnswer, "{t}");
        }
        for t in [
            "excitation 'f1': pole at 3.1000 Hz dropped by the backward model-order test (it x, below the χ² threshold 3.0)",
            "m1: complex residues (rotated by 0.010 rad onto the real line)",
            "the 0 Hz line is left out (27 values): a high-pass (AC coupling) makes it 0",
            "set-up 'A': rejected the mode at 3.1818 Hz: 7 candidate modes for six rigid-body modes; this one has the least evidence",
            "something nobody anticipated",
        ] {
            assert_eq!(classify(t), Class::Note, "{t}");
        }
    }

    #[test]
    fn default_output_is_one_line_per_stage_plus_the_answer_changing_ones() {
        let mut c = Collector::default();
        c.push(
            "modal-fit",
            "excitation 'a': pole at 1.0 Hz dropped by the backward model-order test",
        );
        c.push(
            "modal-fit",
            "excitation 'b': pole at 2.0 Hz dropped by the backward model-order test",
        );
        c.push(
            "modal-fit",
            "excitation 'b': pole at 2.0 Hz dropped by the backward model-order test",
        );
        c.push("rb-solve", "Φ0 is poorly conditioned (cond = 1e9)");
        assert_eq!(
            c.lines(false),
            vec![
                "modal-fit: 2 notes on how the answer was reached; run with -v to list them"
                    .to_string(),
                "rb-solve: warning: Φ0 is poorly conditioned (cond = 1e9)".to_string(),
            ]
        );
        let all = c.lines(true);
        assert_eq!(all.len(), 3);
        assert_eq!(all.iter().filter(|l| l.contains(": note: ")).count(), 2);
        assert_eq!(
            all[2],
            "rb-solve: warning: Φ0 is poorly conditioned (cond = 1e9)"
        );
        assert!(Collector::default().lines(false).is_empty());
    }

    /// modal-fit's typed diagnostics are classified by severity and explained by kind,
    /// whatever their text says: a note whose text holds an answer-changing phrase stays a
    /// note, a warning whose text holds none is printed; the summary names the notes' kinds.
    #[test]
    fn typed_diagnostics_are_classified_by_kind_not_text() {
        use rbprops_core::records::DiagnosticSubject;
        let d = |kind, severity, message: &str| Diagnostic {
            stage: "modal-fit".into(),
            kind,
            severity,
            subject: DiagnosticSubject {
                setup: Some("A".into()),
                ..Default::default()
            },
            message: message.into(),
            advice: String::new(),
        };
        let note = StageWarning::from_diagnostic(&d(
            DiagnosticKind::RepeatedRoot,
            Severity::Note,
            "the old fit failed and is missing; cannot be separated",
        ));
        assert_eq!(note.class(), Class::Note);
        assert_eq!(note.explanation(), DiagnosticKind::RepeatedRoot.sentence());
        let warning = StageWarning::from_diagnostic(&d(
            DiagnosticKind::FitErrorAboveNoise,
            Severity::Warning,
            "median fit error 1.1",
        ));
        assert_eq!(warning.class(), Class::ChangesAnswer);
        assert_eq!(
            warning.explanation(),
            DiagnosticKind::FitErrorAboveNoise.sentence()
        );
        let mut c = Collector::default();
        c.add(note);
        c.add(StageWarning::from_diagnostic(&d(
            DiagnosticKind::FitChoice,
            Severity::Note,
            "poly-reference fit kept",
        )));
        c.add(warning);
        assert_eq!(
            c.lines(false),
            vec![
                "modal-fit: warning: set-up A: median fit error 1.1".to_string(),
                "modal-fit: 2 notes (repeated root, fit choice) on how the answer was reached (1 warning above); run with -v to list them".to_string(),
            ]
        );
    }
}
