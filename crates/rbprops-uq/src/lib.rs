//! **rbprops-uq**: standard errors of the inertia estimates by a parametric bootstrap at
//! the FRF level.
//!
//! The linearised propagation of `rbprops-inertia` treats every residue as independent.
//! They are not: the residues of one excitation share its pole estimates, and frequency
//! and damping errors feed the residues. This crate resamples the *measurements*
//! instead, so every such correlation is carried through the same code that made the
//! estimate.
//!
//! # Procedure ([`bootstrap()`])
//! 1. **Fitted model.** For each excitation the selection uses (with poles shared per
//!    set-up: every fitted excitation of its set-up), the poles of the `ModalFitRecord`
//!    and LSFD residues (`rbprops_modal::lsfd::fit_residues`, residual terms as in the
//!    modal fit) give the synthesised FRFs `S_kil` on the fit's band (`band_hz` of the
//!    record). This is the modal fit's own synthesis (its final residues are an LSFD
//!    solution for its final poles). When the modal fit weighted its lines by measured
//!    quality (`modal-fit --weight variance|coherence`, the default on `frf-est` output),
//!    the model and every replicate's refit take the same weights
//!    ([`BootstrapOptions::fit_weighting`]): the bootstrap spreads the estimator that made
//!    the record, not an unweighted one (which on impact tests was 30× wider and lost its
//!    replicates to poles it does not hold optimal). The FRFs come as an
//!    `rbprops_core::FrfSource`: each excitation's model is made whole (steps 1–2 and its
//!    replicates' grid) from that excitation alone and its measured values let go, so the
//!    set is never held (a reader may decode it from a file one excitation at a time).
//! 2. **Noise model** ([`noise`]): per excitation k and channel i,
//!    `E|H − S|² = σ²_kil = a²_ki |S_kil|² + b²_ki`, fitted by maximum likelihood to the
//!    residual measured − synthesised, with a degrees-of-freedom correction for the
//!    parameters the modal fit spent. Structured misfit (a run of lines whose residual
//!    power is far above the noise, e.g. a weakly excited mode the fit left out) is not
//!    noise: such lines are found by a moving average of `|r|²/σ²`, left out of the noise
//!    fit, and the bootstrap's centre takes the measured values there (`S'` below), so
//!    every replicate carries the misfit the measurement carries.
//!    Where the FRF estimator knows each line's variance (`frf-est`'s line-variance topic,
//!    or an export's coherence and averages: [`LineVariance`]), that variance replaces the
//!    fitted `σ²` on every channel it covers, times the factor by which a window's
//!    line-to-line correlation raises the noise of a run of lines; the estimates' method
//!    text ([`method_text`], `uncertainty_source`) says which was used. When the
//!    estimator also gives the force noise's error common to an excitation's channels
//!    (`frf-est`: `Ĥ = H(1 + ε)`, [`LineVariance::common`]), each replicate draws one `ε`
//!    per excitation for all its channels, with the force window's line correlation
//!    (`rbprops_core::CommonRelativeError`; on impact tests Jzz was covered 52 % of the
//!    time without it, 95 % with it).
//! 3. **Replicates** b = 1..B: `H*_kil = S'_kil + σ_kil (n₁ + i n₂)/√2` with standard
//!    normals from a ChaCha8 stream seeded by `(seed, b)`, drawn excitation by excitation,
//!    channel by channel, line by line — on every q-th line of the band ([`decimation`]:
//!    as many lines as keep 2 per half-power half-bandwidth of the narrowest mode), each
//!    grid line taking the mean `σ²` of its run of q lines divided by q. The estimators'
//!    normal equations are sums over lines of smooth functions times the noise; the sum
//!    over every q-th line with `σ²/q` has the same mean and covariance while the FRF is
//!    smooth over the run, so the replicates spread as they would on every line at a q-th
//!    of the cost (q = 58 at 102,401 lines of the demo; 1 at its 1,601).
//! 4. **Re-identification** ([`Reidentify`]): by default the modal fit's final stages from
//!    the record's poles: variable-projection refinement of the poles and LSFD residues
//!    on the replicate (`Refine`); or the whole modal fit with given `FitOptions` and each
//!    selected mode found again by MAC ≥ 0.9 and the nearest pole (`Full`). A pole that
//!    moves more than 10 half-power half-bandwidths, leaves the band or the damping range
//!    fails the replicate when the selection takes a shape from it; a pole it does not
//!    use (a spurious or weakly excited estimate the record keeps) is held at the
//!    record's value instead, and the residues fitted at the poles so held.
//! 5. **Estimation**: `rbprops_inertia::solve` with the caller's options (modal
//!    estimators only, no reference, no propagation) on the replicate's modal record and
//!    the same selection (mode numbers re-mapped). A replicate fails for an estimator when
//!    the solve fails, gives no estimate, or uses other modes than the original estimate.
//! 6. **Statistics** per estimate: standard error = sample standard deviation of the
//!    successful replicates, bias = their mean − the estimate, percentile 95 % interval
//!    `[q2.5, q97.5]`; the std-based interval is `estimate ± 1.96 std`
//!    ([`BootstrapEstimate::normal_95`]). A replicate beyond [`RAN_WIDE_SIGMAS`] robust
//!    standard deviations (`1.4826 × MAD`) of the others on some property ran wide (an
//!    estimator failing on a draw, not noise) and counts as failed, with its reason.
//!    More than 5 % failed replicates give a warning (the survivors may understate the
//!    spread).
//!
//! Replicates run in parallel (rayon); each depends only on its own seed and the results
//! are reduced in replicate order, so the output is identical for any thread count.
//!
//! # Calibration (demo campaign: Test Case II, 1 % relative FRF noise)
//! `cargo run --release -p rbprops-cli --example calibration -- 50` (50 seeds, B = 100),
//! coverage of the 95 % intervals, properties m cx cy cz Jxx Jyy Jzz Jxy Jxz Jyz:
//!
//! | | m | cx | cy | cz | Jxx | Jyy | Jzz | Jxy | Jxz | Jyz |
//! |---|---|---|---|---|---|---|---|---|---|---|
//! | TN linearised | 98 | 98 | 98 | 94 | 86 | 88 | 92 | 80 | 80 | 88 |
//! | TN bootstrap ±1.96σ | 100 | 98 | 98 | 92 | 90 | 92 | 96 | 96 | 96 | 98 |
//! | TN bootstrap percentile | 94 | 96 | 88 | 90 | 90 | 90 | 92 | 94 | 96 | 96 |
//! | BC linearised | 98 | 98 | 6 | 90 | 88 | 88 | 92 | 78 | 80 | 88 |
//! | BC bootstrap ±1.96σ | 100 | 92 | 26 | 96 | 90 | 92 | 96 | 96 | 96 | 98 |
//! | BC bootstrap percentile | 92 | 86 | 24 | 94 | 92 | 90 | 92 | 94 | 96 | 96 |
//!
//! The bootstrap σ matches the spread of the estimates over the seeds (sd/σ 0.7–1.1 for
//! every property; the linearised σ is too small by up to 1.5× for the inertia). The
//! std-based interval calibrates better than the percentile one and is the one written
//! into the records. Bretl–Conti's c_y is *biased*, not under-dispersed: its error is
//! −2.6 bootstrap σ on average with the right spread, the same in every seed (the
//! force1 fit leaves out the 1.13 Hz mode and BC's exact inverse passes the resulting
//! shape error of modes 1 and 3 to c_y; Toivola–Nuutila is unbiased on the same shapes).
//! A bias that is the same in every replicate cannot be seen by any resampling.
//! About 2 % of replicates fail (a weakly excited mode whose damping the refinement
//! drives to 0); 3.5 s per run with B = 100 (35 ms per replicate) on a shared 2-core
//! machine.
//!
//! At 102,401 lines × 3 excitations `rb-solve` with the bootstrap took 47–199 s on every
//! line; on the grid it takes 3.6× the CPU time of the process without the bootstrap
//! (docs/results.md, "rb-solve's bootstrap at scale").
//!
//! No I/O: data in, data (or typed errors) out.

#![warn(missing_docs)]

pub mod bootstrap;
pub mod error;
pub mod model;
pub mod noise;
pub mod reidentify;
pub mod scratch;

pub use bootstrap::{
    apply, bootstrap, estimate_vector, method_text, solve_with_bootstrap, BootstrapEstimate,
    BootstrapOptions, BootstrapOutput, ExcitationNoise, N_PROPS, PROPERTY_NAMES, RAN_WIDE_SIGMAS,
};
pub use error::UqError;
pub use model::{decimation, CommonDraw, Draws, ExcitationModel, FittedModel, Grid, LineVariance};
pub use noise::{fit_channel, fit_channel_noise, ChannelFit};
pub use rbprops_core::noise::NoiseModel;
pub use reidentify::{MatchTolerances, Reidentify, ReplicateModes};
pub use scratch::{MemoryStore, Scratch, ValueStore};
