//! Where the model check spends its time, for the `check_speed` bench. Compiled to
//! no-ops unless the `phase-timing` feature is on, so the library pays nothing for it.
//!
//! Each phase accumulates the wall time of its calls summed over the threads that made
//! them (thread-seconds: with two threads busy, a phase can exceed the elapsed time) and
//! its number of calls. Phases nest: an LM fit's time includes the Jacobians and model
//! evaluations it makes.

/// Names of the phases, by index.
pub const PHASES: [&str; 13] = [
    "model evaluations (predict)",
    "finite-difference Jacobians",
    "LM fit: baseline",
    "LM fit: candidate refits",
    "LM fit: other (backward, gauges)",
    "LM linear algebra (normal equations, steps)",
    "noise model (estimate, re-estimate)",
    "screening: current span and chord solver",
    "screening: score tests",
    "screening: profiles (grid)",
    "screening: in-band resonance",
    "held-out residuals",
    "Wald statistic (projected)",
];

/// Phase indices (see [`PHASES`]).
pub const PREDICT: usize = 0;
/// Finite-difference Jacobians.
pub const JACOBIAN: usize = 1;
/// The baseline fit.
pub const FIT_BASELINE: usize = 2;
/// The refits of candidate effects.
pub const FIT_REFIT: usize = 3;
/// Other fits (backward elimination, gauge checks).
pub const FIT_OTHER: usize = 4;
/// Levenberg–Marquardt linear algebra (normal equations, steps).
pub const LM_ALGEBRA: usize = 5;
/// The noise model (estimate and re-estimate).
pub const NOISE: usize = 6;
/// The screening's span of the current model and its chord solver.
pub const SCREEN_SPAN: usize = 7;
/// The screening's score tests.
pub const SCREEN_SCORE: usize = 8;
/// The screening's profiles over a grid.
pub const SCREEN_PROFILE: usize = 9;
/// The screening's in-band resonance search.
pub const SCREEN_RESONANCE: usize = 10;
/// Held-out residuals (cross-validation).
pub const HELD_OUT: usize = 11;
/// The projected Wald statistic of a refitted effect (docs/physics.md, M6e).
pub const WALD: usize = 12;

#[cfg(feature = "phase-timing")]
mod imp {
    use std::sync::atomic::{AtomicU64, Ordering};
    const N: usize = super::PHASES.len();
    static NANOS: [AtomicU64; N] = [const { AtomicU64::new(0) }; N];
    static CALLS: [AtomicU64; N] = [const { AtomicU64::new(0) }; N];

    /// Charges the time from its creation to its drop to a phase.
    pub struct Span {
        phase: usize,
        start: std::time::Instant,
    }

    impl Drop for Span {
        fn drop(&mut self) {
            let t = self.start.elapsed().as_nanos() as u64;
            NANOS[self.phase].fetch_add(t, Ordering::Relaxed);
            CALLS[self.phase].fetch_add(1, Ordering::Relaxed);
        }
    }

    /// A guard that adds the time until it is dropped to `phase`'s total.
    #[inline]
    pub fn span(phase: usize) -> Span {
        Span {
            phase,
            start: std::time::Instant::now(),
        }
    }

    /// Calls and seconds per phase since the last [`reset`].
    pub fn totals() -> Option<Vec<(u64, f64)>> {
        Some(
            (0..N)
                .map(|i| {
                    (
                        CALLS[i].load(Ordering::Relaxed),
                        NANOS[i].load(Ordering::Relaxed) as f64 * 1e-9,
                    )
                })
                .collect(),
        )
    }

    /// Sets every phase's calls and seconds to zero.
    pub fn reset() {
        for i in 0..N {
            NANOS[i].store(0, Ordering::Relaxed);
            CALLS[i].store(0, Ordering::Relaxed);
        }
    }
}

#[cfg(not(feature = "phase-timing"))]
mod imp {
    /// Without `phase-timing`: a guard that records nothing.
    pub struct Span;

    /// Without `phase-timing`: does nothing.
    #[inline(always)]
    pub fn span(_phase: usize) -> Span {
        Span
    }

    /// Without `phase-timing`: nothing was counted.
    pub fn totals() -> Option<Vec<(u64, f64)>> {
        None
    }

    /// Without `phase-timing`: nothing to reset.
    pub fn reset() {}
}

/// Zeroes the counters (between the bench's cases).
pub use imp::reset;
/// `(calls, thread-seconds)` per phase since the last [`reset`], or `None` without
/// `phase-timing`.
pub use imp::totals;
/// `let _t = span(PHASE);` charges the time until `_t` is dropped to the phase (a
/// no-op without `phase-timing`).
pub use imp::{span, Span};
