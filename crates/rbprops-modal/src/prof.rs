//! Per-phase wall-clock accounting of the fit, for the `timing` example. Compiled to
//! no-ops unless the `phase-timing` feature is on, so the library pays nothing for it.
//!
//! Phases: 0 LSCF sweep, 1 stabilisation selection, 2 pole refinement, 3 candidate
//! screening, 4 LSCF normal-equation sums, 5 companion eigenvalues, 6 LSFD residues,
//! 7 synthesis (unused since the LSFD residues return the fitted FRFs: their cost is
//! in phase 6; kept so that the phase indices stay stable). The poly-reference fit
//! charges its sweep's reduced normal equations to 4, its companion eigenvalues to 5,
//! and splits its pole refinement (2) into 8 trials (the LSFD solve at each trial
//! pole set), 9 normal equations and 10 the damped steps' dense solves; 11 its
//! sweep's solves for the denominator coefficients.

/// Names of the phases, by index.
pub const PHASES: [&str; N] = [
    "LSCF sweep (total)",
    "stabilisation selection",
    "pole refinement",
    "candidate screening",
    "  LSCF sums",
    "  companion eigenvalues",
    "LSFD residues",
    "synthesis",
    "  refinement trials",
    "  refinement normal equations",
    "  refinement steps",
    "  pLSCF denominator solves",
];

/// Number of phases.
const N: usize = 12;

#[cfg(feature = "phase-timing")]
mod imp {
    use std::sync::atomic::{AtomicU64, Ordering};
    static NANOS: [AtomicU64; super::N] = [const { AtomicU64::new(0) }; super::N];
    static CALLS: [AtomicU64; super::N] = [const { AtomicU64::new(0) }; super::N];

    #[inline]
    /// Runs `f`, charging its wall time to `phase` (a no-op without `phase-timing`).
    pub fn time<R>(phase: usize, f: impl FnOnce() -> R) -> R {
        let t = std::time::Instant::now();
        let r = f();
        NANOS[phase].fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
        CALLS[phase].fetch_add(1, Ordering::Relaxed);
        r
    }

    /// `(calls, seconds)` per phase since the start, or `None` without `phase-timing`.
    pub fn totals() -> Option<Vec<(u64, f64)>> {
        Some(
            (0..super::N)
                .map(|i| {
                    (
                        CALLS[i].load(Ordering::Relaxed),
                        NANOS[i].load(Ordering::Relaxed) as f64 * 1e-9,
                    )
                })
                .collect(),
        )
    }
}

#[cfg(not(feature = "phase-timing"))]
mod imp {
    #[inline(always)]
    /// Runs `f`, charging its wall time to `phase` (a no-op without `phase-timing`).
    pub fn time<R>(_phase: usize, f: impl FnOnce() -> R) -> R {
        f()
    }

    /// `(calls, seconds)` per phase since the start, or `None` without `phase-timing`.
    pub fn totals() -> Option<Vec<(u64, f64)>> {
        None
    }
}

pub use imp::time;
pub use imp::totals;
