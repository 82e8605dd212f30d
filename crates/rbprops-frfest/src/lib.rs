//! FRF estimation from impact or shaker time histories: the numerics behind `frf-est`
//! (issue #36). No I/O.
//!
//! The chain, per excitation:
//!
//! 1. [`find_hits`] cuts a continuous throughput record into hit records (level trigger with
//!    a pretrigger and a holdoff); hits too close to either end are reported, not dropped.
//! 2. [`inspect_hit`] checks each hit record: trigger, pulse, double hits, overload
//!    (clipping), too-weak hits; typed [`RejectReason`]s.
//! 3. [`ForceWindow`] and [`ResponseWindow`] (with [`auto_tau`]) give the window sample
//!    values; [`HitWindows`] applies them, the exponential one to force *and* response.
//! 4. [`SpectralSums`] accumulates `S_ff`, `S_xf`, `S_xx` over accepted hits (one real FFT
//!    plan per record length, no allocation per hit), so a live mode can update per hit.
//! 5. [`SpectralSums::h1`], [`SpectralSums::h2`], [`SpectralSums::hv`] give the FRFs on the
//!    one-sided DFT lines `f_k = k f_s/N`, with ordinary or multiple coherence and each
//!    line's variance ([`FrfEstimate`]); [`smoothed_variance`] pools the variance over
//!    neighbouring lines; [`line_correlation`] gives the windows' line-to-line noise
//!    correlation; [`quality`] the relative standard error and how many hits would halve it;
//!    [`convert_quantity`] turns accelerance into mobility or receptance.
//!
//! # Conventions
//!
//! Time dependence `e^{+iωt}` (docs/conventions.md §1), so the DFT is the ordinary forward
//! transform `X_k = Σ_n x[n] e^{−2πikn/N}` (no scaling: the FRF is a ratio of sums, and
//! the spectral sums are raw DFT products). `S_xf = Σ_d X_d F̄_d` (response times the
//! conjugate force), `S_ff = Σ_d F_d F_dᴴ`, `S_xx = Σ_d |X_d|²`, summed over the `n_d`
//! accepted hits `d`. MIMO: `X = H F` with `H` of `n_resp × n_refs`.
//!
//! Everything is single-threaded and runs in a fixed order: the same input gives
//! bit-identical output.

#![warn(missing_docs)]
// `!(x > 0.0)` is deliberate throughout: it is true for NaN, which must be refused too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod estimate;
pub mod hit;
pub mod spectra;
pub mod window;

pub use estimate::{
    coherence_line_variance, convert_quantity, quality, smoothed_variance, ConditioningOptions,
    Estimator, FrfEstimate, Quality, Quantity, SmoothedVariance,
};
pub use hit::{
    find_hits, inspect_hit, Channel, DoubleHit, Edge, HitCheckOptions, HitReport, RejectReason,
    Trigger, TriggerLevel, TriggerOptions,
};
pub use rbprops_core::c64;
pub use spectra::SpectralSums;
pub use window::{
    auto_tau, exponential_line_correlation, line_correlation, pulse_centroid, ForceNoiseBins,
    ForceWindow, HitWindows, ResponseWindow, MAX_FORCE_NOISE_BINS,
};

/// Errors of the estimators. Each names what is wrong and where.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrfError {
    /// A record whose length differs from the record length the sums were planned for.
    #[error("{what} has {got} samples, the record length is {expected}")]
    Length {
        /// Which signal.
        what: String,
        /// Its length.
        got: usize,
        /// The planned record length.
        expected: usize,
    },
    /// A call with the wrong number of channels.
    #[error("{what}: {got} channels given, {expected} expected")]
    Channels {
        /// Which signals.
        what: &'static str,
        /// How many were given.
        got: usize,
        /// How many the sums hold.
        expected: usize,
    },
    /// No hit has been added yet.
    #[error("no hits averaged")]
    NoAverages,
    /// `S_ff` is singular or ill-conditioned at a line (coherent inputs, a dead reference,
    /// fewer hits than references).
    #[error(
        "the force cross-spectral matrix is singular or ill-conditioned at line {line} ({freq_hz} Hz): condition number {condition:e} (> {max:e}); the references are coherent or too few hits were averaged"
    )]
    IllConditioned {
        /// DFT line index k.
        line: usize,
        /// Its frequency `k f_s/N`.
        freq_hz: f64,
        /// λ_max/λ_min of S_ff (infinite when λ_min ≤ 0).
        condition: f64,
        /// The limit.
        max: f64,
    },
    /// An estimator that exists only for one reference.
    #[error("{0} is defined here for one reference (SIMO) only")]
    SimoOnly(&'static str),
    /// A band outside the one-sided lines.
    #[error("band {start}..{end} is outside lines 0..{lines}")]
    Band {
        /// First line.
        start: usize,
        /// One past the last line.
        end: usize,
        /// The number of one-sided lines `N/2 + 1`.
        lines: usize,
    },
    /// A bad argument (record length, sampling rate, window).
    #[error("{0}")]
    Invalid(String),
}
