//! The bootstrap on the demo campaign (Test Case II, 1 % relative FRF noise).

use crate::common;
use rbprops_uq::*;

fn run(c: &common::Case, opts: &BootstrapOptions) -> BootstrapOutput {
    let out =
        rbprops_inertia::solve(&c.geometry, &c.modal, &c.selection, None, &c.solve_opts).unwrap();
    run_bootstrap(c, &out, opts, None)
}

/// Identical output (bit for bit) with 1 and 2 rayon threads.
#[test]
fn identical_for_any_thread_count() {
    let c = common::case("demo", 5, None);
    let opts = BootstrapOptions {
        replicates: 12,
        seed: 9,
        ..Default::default()
    };
    let pool = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    let a = pool(1).install(|| run(&c, &opts));
    let b = pool(2).install(|| run(&c, &opts));
    assert_eq!(a, b);
    // A different seed gives different replicates.
    let d = pool(2).install(|| {
        run(
            &c,
            &BootstrapOptions {
                seed: 10,
                ..opts.clone()
            },
        )
    });
    assert_ne!(a.estimates[0].samples, d.estimates[0].samples);
}

/// The noise model recovers the simulation's 1 % relative noise per channel. For each
/// channel ~1600 lines give the relative level to ~2 % (sd); the median over the 27
/// channels is within 3 %, every channel within 15 % (misfit lines are excluded).
#[test]
fn noise_model_recovers_the_simulated_level() {
    let c = common::case("demo", 6, Some(0.02));
    let out = run(
        &c,
        &BootstrapOptions {
            replicates: 2,
            ..Default::default()
        },
    );
    let mut rel: Vec<f64> = out
        .noise
        .iter()
        .flat_map(|e| e.channels.iter().map(|n| n.relative / 0.02))
        .collect();
    rel.sort_by(f64::total_cmp);
    assert!(rel.len() >= 18, "{} channels", rel.len());
    let median = rel[rel.len() / 2];
    assert!((median - 1.0).abs() < 0.03, "{rel:?}");
    assert!(rel.iter().all(|r| (r - 1.0).abs() < 0.15), "{rel:?}");
}

/// Small coverage check on Toivola–Nuutila (whose estimates are unbiased here): over 6
/// seeds × 10 properties = 60 intervals with B = 30, ±1.96σ must cover at least 48 (80 %).
/// With true 95 % coverage P(fewer than 48 of 60) < 1e-4 for independent intervals; the
/// properties of one seed are correlated, which widens that tail, so the bound is loose.
/// Standard errors too small by a factor of two (coverage ≈ 67 %) fail it.
#[test]
fn intervals_cover_the_truth() {
    let mut covered = 0;
    let mut total = 0;
    for seed in 101..=106 {
        let c = common::case("demo", seed, None);
        let out = run(
            &c,
            &BootstrapOptions {
                replicates: 30,
                ..Default::default()
            },
        );
        let tv = common::truth_vector(&c.truth);
        let tn = out
            .estimates
            .iter()
            .find(|e| e.method == "toivola_nuutila")
            .unwrap();
        assert!(
            tn.failed <= 3,
            "{} failed: {:?}",
            tn.failed,
            tn.failure_reasons
        );
        for k in 0..N_PROPS {
            total += 1;
            covered += ((tn.estimate[k] - tv[k]).abs() <= 1.96 * tn.std[k]) as usize;
        }
    }
    assert!(covered >= 48, "{covered} of {total}");
}

/// `apply` writes the bootstrap errors into both the estimate and its projected version.
#[test]
fn apply_fills_the_records() {
    let c = common::case("demo", 7, None);
    let (out, boot) = solve_with_bootstrap(
        &c.geometry,
        &c.modal,
        &c.selection,
        &c.frf,
        &c.solve_opts,
        &BootstrapOptions {
            replicates: 8,
            ..Default::default()
        },
        None,
    )
    .unwrap();
    let boot = boot.unwrap();
    for e in &out.estimates {
        let b = boot
            .estimates
            .iter()
            .find(|b| e.method.base() == b.method)
            .unwrap();
        assert_eq!(e.uncertainty_method, "bootstrap");
        assert_eq!(e.mass_std_kg, b.std[0]);
        assert_eq!(e.com_std_m, [b.std[1], b.std[2], b.std[3]]);
        assert_eq!(e.inertia_cm_std_kg_m2[0][1], b.std[7]);
        assert_eq!(e.products_of_inertia_std_kg_m2.yz, b.std[9]);
        assert!(b.std.iter().all(|s| s.is_finite() && *s > 0.0));
        assert_eq!(estimate_vector(e), b.estimate);
    }
}

/// Issue 41: a model and replicates kept in scratch stores (here in memory, holding
/// nothing) give the bootstrap bit for bit as held, with poles per excitation and per
/// set-up (a group of several excitations refined jointly, its draws read channel by
/// channel); the stores were made (the model's, and one per replicate and group), and
/// the model's grids read back are those held. Stores that cannot be made: held.
#[test]
fn kept_in_scratch_stores_the_bootstrap_is_the_same_bit_for_bit() {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let mut c = common::case("demo", 5, None);
    for poles in [
        rbprops_modal::PoleMode::PerExcitation,
        rbprops_modal::PoleMode::PerSetup,
    ] {
        let fit = rbprops_modal::FitOptions {
            poles,
            ..Default::default()
        };
        c.modal = rbprops_modal::fit_campaign(&c.geometry, &c.frf, &fit)
            .unwrap()
            .record;
        c.selection = rbprops_ni::select_modes(&c.geometry, &c.frf, &c.modal, &Default::default())
            .unwrap()
            .record;
        let made = std::sync::Arc::new(AtomicUsize::new(0));
        let counter = made.clone();
        let scratch = Scratch::new(
            move || {
                counter.fetch_add(1, Ordering::Relaxed);
                Ok(Box::new(MemoryStore::default()) as Box<dyn ValueStore>)
            },
            0,
        );
        let held = BootstrapOptions {
            replicates: 6,
            seed: 4,
            ..Default::default()
        };
        let stored = BootstrapOptions {
            scratch: Some(scratch.clone()),
            ..held.clone()
        };
        let a = run(&c, &held);
        let b = run(&c, &stored);
        assert_eq!(a, b, "{poles:?}");
        // No store can be made (no writable temporary directory): held, the same.
        let none = BootstrapOptions {
            scratch: Some(Scratch::new(|| Err(std::io::Error::other("no store")), 0)),
            ..held.clone()
        };
        assert_eq!(run(&c, &none), a, "{poles:?}");
        let groups = fitted(&c, &Draws::default()).groups.len();
        assert!(groups >= 1);
        assert_eq!(made.load(Ordering::Relaxed), 1 + 6 * groups, "{poles:?}");
        let plain = fitted(&c, &Draws::default());
        let kept = fitted(
            &c,
            &Draws {
                scratch: Some(&scratch),
                ..Default::default()
            },
        );
        for i in 0..plain.excitations.len() {
            assert!(kept.excitations[i].draw_band.channels.is_empty());
            let (p, k) = (plain.grid(i).unwrap(), kept.grid(i).unwrap());
            assert_eq!(format!("{:?}", p.band), format!("{:?}", k.band));
            assert_eq!(p.sd, k.sd);
        }
        if poles == rbprops_modal::PoleMode::PerSetup {
            assert!(
                plain.groups.iter().any(|g| g.len() > 1),
                "{:?}",
                plain.groups
            );
        }
    }
}

/// The fitted model of `c` (residual terms on, pole mode from the record) with `draws`.
fn fitted(c: &common::Case, draws: &Draws) -> FittedModel {
    FittedModel::new(
        &c.geometry,
        &c.frf,
        &c.modal,
        &c.selection,
        true,
        None,
        draws,
    )
    .unwrap()
}

/// [`bootstrap`] of `c`'s estimates `out` with `opts` and the line variances `given`.
fn run_bootstrap(
    c: &common::Case,
    out: &rbprops_inertia::SolveOutput,
    opts: &BootstrapOptions,
    given: Option<&LineVariance>,
) -> BootstrapOutput {
    bootstrap(
        &c.geometry,
        &c.frf,
        &c.modal,
        &c.selection,
        &c.solve_opts,
        &out.estimates,
        opts,
        given,
    )
    .unwrap()
}

/// [`model_line_variance`]'s lines (the fitted band's) all set to `sigma2`.
fn constant_line_variance(c: &common::Case, sigma2: f64) -> LineVariance {
    let mut given = model_line_variance(c, 1.0);
    given.sigma2.iter_mut().for_each(|s| {
        if s.is_finite() {
            *s = sigma2
        }
    });
    given
}

/// The line variances of `c` that the residuals' noise model gives every line of the fitted
/// band, times `scale`, on the FRF layout (NaN off the band).
fn model_line_variance(c: &common::Case, scale: f64) -> LineVariance {
    let model = fitted(&c, &Draws::default());
    let (nc, nl) = (c.frf.n_channels, c.frf.n_lines());
    let mut sigma2 = vec![f64::NAN; c.frf.values.len()];
    for e in &model.excitations {
        for (ch, nz) in e.noise.iter().enumerate() {
            // Every line is on the grid (no decimation): the grid's values are the centre.
            for (l, z) in e.draw_band.channels[ch].iter().enumerate() {
                sigma2[(e.excitation * nc + ch) * nl + e.band.first_line + l] =
                    scale * nz.variance(*z);
            }
        }
    }
    LineVariance {
        sigma2,
        correlation_factor: 1.0,
        source: "test".into(),
        common: Vec::new(),
    }
}

/// The force noise's common error moves every channel of its excitation by the same
/// relative amount: with no per-channel noise and one bin at the pulse's centroid (a pure
/// real gain), a replicate is `H (1 + ε)` with one real ε on every channel and line of
/// that excitation, and the other excitations are drawn as before (here: exactly their
/// centre). The method text says so.
#[test]
fn a_common_error_moves_every_channel_of_its_excitation_alike() {
    let c = common::case("demo", 8, None);
    let mut given = constant_line_variance(&c, 0.0);
    let nl = c.frf.n_lines();
    let plain = fitted(&c, &Draws::default());
    let ex0 = plain.excitations[0].excitation;
    given.common = vec![None; c.frf.n_excitations];
    given.common[ex0] = Some(rbprops_core::CommonRelativeError {
        relative_variance: vec![1e-6; nl],
        times_s: vec![0.0],
        weights: vec![1.0],
    });
    let model = fitted(
        &c,
        &Draws {
            line_variance: Some(&given),
            ..Default::default()
        },
    );
    use rand::SeedableRng;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let mut gains = Vec::new();
    for (i, e) in model.excitations.iter().enumerate() {
        let grid = model.grid(i).unwrap();
        let y = e.draw(&grid, &mut rng);
        let mut eps: Vec<rbprops_core::c64> = Vec::new();
        for (y, h) in y.iter().zip(&grid.band.channels) {
            for (y, h) in y.iter().zip(h) {
                if h.norm() > 0.0 {
                    eps.push(y / h - 1.0);
                }
            }
        }
        if e.excitation != ex0 {
            assert!(e.common.is_none());
            assert!(eps.iter().all(|x| x.norm() == 0.0), "{}", e.id);
            continue;
        }
        let first = eps[0];
        assert!(first.re.abs() > 1e-9 && first.im.abs() < 1e-15, "{first}");
        assert!(eps
            .iter()
            .all(|x| (x - first).norm() < 1e-12 * first.norm().max(1.0)));
        gains.push(first.re);
    }
    assert_eq!(gains.len(), 1);
    let out =
        rbprops_inertia::solve(&c.geometry, &c.modal, &c.selection, None, &c.solve_opts).unwrap();
    let text = method_text(&run_bootstrap(
        &c,
        &out,
        &BootstrapOptions {
            replicates: 2,
            ..Default::default()
        },
        Some(&given),
    ));
    assert!(
        text.contains(&format!(
            "on 1 of {} excitations also the force noise's error common to their channels",
            model.excitations.len()
        )),
        "{text}"
    );
}

/// Given line variances replace the residuals' noise model: each line's draw has
/// `√(σ² κ/2)` per part exactly, a channel with an unknown (NaN) line falls back to the
/// noise model, and the method text says which was used.
#[test]
fn line_variances_set_the_draws() {
    let c = common::case("demo", 8, None);
    let mut given = constant_line_variance(&c, 3e-6);
    given.correlation_factor = 2.5;
    // One unknown line on channel 4 of the first fitted excitation.
    let plain = fitted(&c, &Draws::default());
    let e0 = &plain.excitations[0];
    let (nc, nl) = (c.frf.n_channels, c.frf.n_lines());
    given.sigma2[(e0.excitation * nc + 4) * nl + e0.band.first_line + 10] = f64::NAN;
    let model = fitted(
        &c,
        &Draws {
            line_variance: Some(&given),
            ..Default::default()
        },
    );
    let want = (3e-6 * 2.5 / 2.0f64).sqrt();
    for (i, e) in model.excitations.iter().enumerate() {
        assert_eq!(e.decimation, 1);
        for ch in 0..nc {
            let fallback = i == 0 && ch == 4;
            assert_eq!(e.given_variance[ch], !fallback);
            if fallback {
                assert_eq!(e.draw_sd[ch], plain.excitations[0].draw_sd[ch]);
            } else {
                assert!(e.draw_sd[ch].iter().all(|&s| s == want));
            }
        }
    }
    let opts = BootstrapOptions {
        replicates: 4,
        ..Default::default()
    };
    let out =
        rbprops_inertia::solve(&c.geometry, &c.modal, &c.selection, None, &c.solve_opts).unwrap();
    let run = |v: Option<&LineVariance>| run_bootstrap(&c, &out, &opts, v);
    let with = method_text(&run(Some(&given)));
    assert!(
        with.contains("the FRF estimator's line variances (test) times 2.500")
            && with.contains(&format!("on {} of {} channels", 3 * nc - 1, 3 * nc))
            && with.contains("elsewhere a noise model"),
        "{with}"
    );
    let without = method_text(&run(None));
    assert!(
        without.contains("fitted to the modal fit's residuals")
            && !without.contains("line variances"),
        "{without}"
    );
}

/// Line variances 4× the residuals' noise model double the bootstrap's standard errors:
/// the replicates draw the same normals (same seed) scaled by 2, so at 1 % noise the ratio
/// is 2 up to the estimators' curvature (≪ 5 %).
#[test]
fn line_variances_scale_the_standard_errors() {
    let c = common::case("demo", 9, None);
    let opts = BootstrapOptions {
        replicates: 16,
        ..Default::default()
    };
    let out =
        rbprops_inertia::solve(&c.geometry, &c.modal, &c.selection, None, &c.solve_opts).unwrap();
    let run = |v: Option<&LineVariance>| run_bootstrap(&c, &out, &opts, v);
    let four = model_line_variance(&c, 4.0);
    let (a, b) = (run(None), run(Some(&four)));
    for (x, y) in a.estimates.iter().zip(&b.estimates) {
        for (k, name) in PROPERTY_NAMES.iter().enumerate() {
            let r = y.std[k] / x.std[k];
            assert!((r - 2.0).abs() < 0.1, "{} {name}: ratio {r}", x.method);
        }
    }
}

/// On a fine frequency grid (12,801 lines: about 17 per half-bandwidth of the first mode)
/// replicates drawn and refitted on every q-th line, each with the noise of its q lines,
/// spread as replicates on every line. With B = 60 each, the ratio of two standard
/// deviations has a relative sd of about 1/√60 ≈ 13 % per property; the median over the
/// ten properties lies within ±25 % (drawing every q-th line with the lines' own variance,
/// not a q-th of it, would read √q ≈ 2.8).
#[test]
fn decimated_replicates_spread_as_every_line() {
    let mut spec = rbprops_sim::CampaignSpec::from_toml_str(
        &rbprops_sim::example("demo")
            .unwrap()
            .replace("lines = 1601", "lines = 12801"),
    )
    .unwrap();
    spec.seed = 11;
    let c = common::case_from_spec(spec);
    let out =
        rbprops_inertia::solve(&c.geometry, &c.modal, &c.selection, None, &c.solve_opts).unwrap();
    let run = |decimate: bool| {
        run_bootstrap(
            &c,
            &out,
            &BootstrapOptions {
                replicates: 60,
                decimate,
                ..Default::default()
            },
            None,
        )
    };
    let (dec, full) = (run(true), run(false));
    assert!(dec.decimation >= 4, "q = {}", dec.decimation);
    assert_eq!(full.decimation, 1);
    for (x, y) in dec.estimates.iter().zip(&full.estimates) {
        let mut r: Vec<f64> = (0..N_PROPS).map(|k| x.std[k] / y.std[k]).collect();
        r.sort_by(f64::total_cmp);
        let median = 0.5 * (r[4] + r[5]);
        assert!((0.8..1.25).contains(&median), "{}: ratios {r:?}", x.method);
    }
}

/// The FRFs of a set handed out one excitation at a time, each a set of its own (as a
/// reader that decodes them from a file does).
struct OneAtATime<'a>(&'a rbprops_core::FrfSet);

impl rbprops_core::FrfSource for OneAtATime<'_> {
    fn quantity(&self) -> rbprops_core::Quantity {
        self.0.quantity
    }
    fn frequency_hz(&self) -> &[f64] {
        &self.0.frequency_hz
    }
    fn n_excitations(&self) -> usize {
        self.0.n_excitations
    }
    fn n_channels(&self) -> usize {
        self.0.n_channels
    }
    fn validate(&self) -> Result<(), rbprops_core::CoreError> {
        self.0.validate()
    }
    fn excitation(
        &self,
        e: usize,
    ) -> Result<rbprops_core::ExcitationFrf<'_>, rbprops_core::CoreError> {
        Ok(rbprops_core::ExcitationFrf::owned(
            self.0.select_excitations(&[e]),
        ))
    }
}

/// The bootstrap reads its model one excitation at a time (issue 41's memory bound): from
/// a source that hands out each excitation alone it gives what it gives on the set in
/// memory, bit for bit, on plain FRFs and on FRFs whose fit took out an exponential
/// window (each excitation then prefiltered as it is read), by refinement and by full
/// refit (which makes the set whole once).
#[test]
fn one_excitation_at_a_time_bootstraps_as_the_whole_set() {
    let mut c = common::case("demo", 6, None);
    let opts = BootstrapOptions {
        replicates: 8,
        seed: 3,
        ..Default::default()
    };
    let compare = |c: &common::Case, opts: &BootstrapOptions| {
        let out = rbprops_inertia::solve(&c.geometry, &c.modal, &c.selection, None, &c.solve_opts)
            .unwrap();
        let whole = run_bootstrap(c, &out, opts, None);
        let one = bootstrap(
            &c.geometry,
            &OneAtATime(&c.frf),
            &c.modal,
            &c.selection,
            &c.solve_opts,
            &out.estimates,
            opts,
            None,
        )
        .unwrap();
        assert!(!whole.estimates.is_empty());
        assert_eq!(whole, one);
    };
    compare(&c, &opts);
    compare(
        &c,
        &BootstrapOptions {
            replicates: 3,
            reidentify: Reidentify::Full(Default::default()),
            ..opts.clone()
        },
    );
    // The same FRFs taken as windowed by a long window (σ = 0.01/s, a tenth of the first
    // mode's decay rate): the fit saw them prefiltered and corrected its poles.
    let w = rbprops_core::WindowCorrection::new(100.0).unwrap();
    let mut modal =
        rbprops_modal::fit_campaign(&c.geometry, &w.prefilter(&c.frf), &Default::default())
            .unwrap()
            .record;
    w.correct_modal_fit(&mut modal, "test").unwrap();
    c.selection = rbprops_ni::select_modes(&c.geometry, &c.frf, &modal, &Default::default())
        .unwrap()
        .record;
    c.modal = modal;
    compare(&c, &opts);
}
