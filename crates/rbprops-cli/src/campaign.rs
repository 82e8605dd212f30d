//! Batch runs: every campaign spec or recording under a directory, in parallel, one
//! summary table. Each item goes through the same stage functions as the executables,
//! so a row equals the single run's row exactly.
//!
//! A campaign file (`campaign.toml` beside the data, or `--config FILE`) sets the options
//! of every item: the modal-fit band and method, the uncertainty method, the exponential
//! window the recordings were processed with, a nominal spec per recording for a model
//! check, and a separate geometry file for UFF exports. See [`CampaignConfig`].

use crate::summary::{self, SummaryRow};
use anyhow::{anyhow, bail, Context, Result};
use rayon::prelude::*;
use rbprops_sim::effects::processing::ExponentialWindow;
use rbprops_sim::CampaignSpec;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// File name of the campaign file looked for in the campaign directory.
pub const CONFIG_FILE: &str = "campaign.toml";

/// File extensions (lower case) of UFF exports read as recordings.
pub const UFF_EXTENSIONS: [&str; 4] = ["uff", "unv", "58", "58b"];

/// True when `p` names a UFF file by its extension.
pub fn is_uff(p: &Path) -> bool {
    p.extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .is_some_and(|e| UFF_EXTENSIONS.contains(&e.as_str()))
}

/// Something the campaign runner can process.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub enum Item {
    /// A campaign spec (TOML): simulated first.
    Spec(PathBuf),
    /// A recording (MCAP file, CSV directory or UFF file) holding geometry and FRFs.
    Recording(PathBuf),
}

impl Item {
    /// The file the item names.
    pub fn path(&self) -> &Path {
        match self {
            Item::Spec(p) | Item::Recording(p) => p,
        }
    }
}

/// The campaign file as written (TOML). Every key is optional; paths are relative to the
/// file's directory.
///
/// ```toml
/// band_hz = [0.5, 10.0]          # modal-fit band (default: the whole axis)
/// method = "lscf"                # modal-fit method: lscf, lsce or circle
/// modes = 6                      # modes in the band (default: from the stabilisation diagram)
/// uncertainty = "linearised"     # rb-solve standard errors: bootstrap (default) or linearised
/// window_time_constant_s = 4.0   # the recordings were processed with e^(−t/τ)
/// nominal = "nominal.toml"       # model check of every recording against this spec
/// check_only = ["channel_gain"]  # screen only these effects (default: the whole catalogue)
/// # or one spec per recording, by glob on the path relative to the campaign directory
/// # (exactly one pattern must match each recording):
/// # [nominal]
/// # "rig-a/*.uff" = "rig-a.toml"
/// # "rig-b/*.uff" = "rig-b.toml"
/// geometry = "geometry.unv"      # node coordinates in a separate UFF file
/// averages = 8                   # FRF exports with coherence: the averages behind them
///
/// [frf_est]                      # time-history exports: frf-est's options (see FrfEstConfig)
/// estimator = "h1"               # h1, h2 or hv
/// window = "auto"                # response window: "auto", "none" or τ in s
/// force_window = [0.01, 0.05]    # s before the trigger, s after the pulse; or "none"
/// min_hits = 3
/// ```
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CampaignConfig {
    /// Modal-fit band `[low, high]` (Hz); default: the whole axis.
    pub band_hz: Option<[f64; 2]>,
    /// Modal-fit method (`lscf`, `lsce` or `circle`).
    pub method: Option<String>,
    /// Modes in the band; default: from the stabilisation diagram.
    pub modes: Option<usize>,
    /// How `rb-solve` obtains standard errors (default: the bootstrap).
    pub uncertainty: Option<crate::stages::UncertaintyChoice>,
    /// Time constant τ (s) of the exponential window `w(t) = e^{−t/τ}` applied to force and
    /// response records before the FRFs were estimated.
    pub window_time_constant_s: Option<f64>,
    /// Nominal spec(s) for the model check: one for all recordings, or one per glob.
    pub nominal: Option<NominalConfig>,
    /// Effect ids the model check screens (`model-check --only`); default: all.
    pub check_only: Option<Vec<String>>,
    /// A UFF file with the nodes (15/2411) and coordinate systems (2420/18) of recordings
    /// that carry only datasets 58.
    pub geometry: Option<PathBuf>,
    /// How time-history exports are made into FRFs (`frf-est`'s options).
    pub frf_est: Option<FrfEstConfig>,
    /// FRF exports with coherence (UFF function type 6): the number of averages behind
    /// them, as `--averages` (each line's variance from its coherence). Recordings that
    /// already carry line variances (time histories, frf-est output, an export that names
    /// its averages) or no coherence are read as they are.
    pub averages: Option<usize>,
}

/// The `[frf_est]` table: `frf-est`'s options for the campaign's time-history exports
/// (UFF 58 function type 1), under the names of its command line. Every key is optional;
/// an absent key keeps frf-est's default ([`crate::frf_est::EstimationOptions`]).
///
/// ```toml
/// [frf_est]
/// estimator = "h1"               # h1 (default), h2 or hv
/// window = "auto"                # response window: "auto" (default), "none" or τ in s
/// window_response_only = false   # the exponential window on the response only
/// force_window = [0.01, 0.05]    # s before the trigger, s after the pulse's end; or "none"
/// taper_s = 0.0                  # cosine taper outside the force window (s)
/// trigger = 0.1                  # trigger level, fraction of the largest |force|
/// pretrigger_s = 0.1             # throughput records: time kept before each trigger
/// record_s = 2.0                 # throughput records: each hit's record length
/// force_range = 250.0            # the force channel's ADC range (± file units)
/// response_range = 50.0          # the response channels' ADC range
/// min_hits = 2                   # fewest accepted hits per excitation (≥ 2)
/// band_hz = [0.5, 12.5]          # band of the FRFs written
/// keep_rejected = false          # average rejected hits as well
/// force_dof = ["201:-X"]         # force channels' DOFs, NODE:DIR
/// ```
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrfEstConfig {
    /// `h1`, `h2` or `hv`.
    pub estimator: Option<String>,
    /// The response window: `auto`, `none` or τ (s).
    pub window: Option<TimeOrName>,
    /// The exponential window on the response only (default: force too).
    pub window_response_only: Option<bool>,
    /// The force window `[pre_s, post_s]`, or `none`.
    pub force_window: Option<PairOrName>,
    /// Cosine taper outside the force window (s).
    pub taper_s: Option<f64>,
    /// Trigger level as a fraction of the record's largest |force|, in (0, 1).
    pub trigger: Option<f64>,
    /// Throughput records: time kept before each trigger (s).
    pub pretrigger_s: Option<f64>,
    /// Throughput records: each hit's record length (s).
    pub record_s: Option<f64>,
    /// The force channel's ADC range (± file units).
    pub force_range: Option<f64>,
    /// The response channels' ADC range (± file units).
    pub response_range: Option<f64>,
    /// Fewest accepted hits per excitation.
    pub min_hits: Option<usize>,
    /// Band `[low, high]` (Hz) of the FRFs written.
    pub band_hz: Option<[f64; 2]>,
    /// Average rejected hits as well.
    pub keep_rejected: Option<bool>,
    /// The force channels' DOFs, `NODE:DIR` (DIR ±X, ±Y, ±Z or ±1..±3).
    pub force_dof: Option<Vec<String>>,
}

/// A time in seconds, or a word (`auto`, `none`).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum TimeOrName {
    /// Seconds.
    Seconds(f64),
    /// A word.
    Name(String),
}

/// Two times in seconds, or a word (`none`).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum PairOrName {
    /// Seconds.
    Seconds([f64; 2]),
    /// A word.
    Name(String),
}

impl FrfEstConfig {
    /// The estimation options, checked; `source` names the campaign file in errors.
    pub fn options(&self, source: &str) -> Result<crate::frf_est::EstimationOptions> {
        let key = Key(source);
        let mut o = crate::frf_est::EstimationOptions::default();
        if let Some(e) = &self.estimator {
            // The names of `frf-est --estimator`, in any case.
            o.estimator = clap::ValueEnum::from_str(e, true)
                .map_err(|_| anyhow::anyhow!("{} = \"{e}\": h1, h2 or hv", key.at("estimator")))?;
        }
        if let Some(w) = self.response_window(key)? {
            o.response_window = w;
        }
        if let Some(r) = self.window_response_only {
            o.exponential_on_force = !r;
        }
        o.force_window = self.force_window(key, o.force_window)?;
        self.hit_checks(key, &mut o)?;
        if let Some([a, b]) = self.band_hz {
            if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
                bail!("{} = [{a}, {b}]: need 0 ≤ FMIN < FMAX", key.at("band_hz"));
            }
            o.band_hz = Some((a, b));
        }
        if let Some(k) = self.keep_rejected {
            o.keep_rejected = k;
        }
        o.force_dofs.extend(self.force_dofs(key)?);
        Ok(o)
    }

    /// `window`: `auto`, `none` or τ (s); `None` when not given.
    fn response_window(&self, key: Key) -> Result<Option<crate::frf_est::WindowChoice>> {
        use crate::frf_est::WindowChoice;
        Ok(match &self.window {
            None => None,
            Some(TimeOrName::Name(w)) if w == "auto" => Some(WindowChoice::Auto),
            Some(TimeOrName::Name(w)) if w == "none" => Some(WindowChoice::None),
            Some(TimeOrName::Name(w)) => {
                bail!(
                    "{} = \"{w}\": \"auto\", \"none\" or τ in seconds",
                    key.at("window")
                )
            }
            Some(TimeOrName::Seconds(t)) => {
                key.positive(Some(*t), "window")?;
                Some(WindowChoice::Exponential(*t))
            }
        })
    }

    /// `force_window` and its `taper_s`, over the default window `default`.
    fn force_window(
        &self,
        key: Key,
        default: Option<rbprops_frfest::ForceWindow>,
    ) -> Result<Option<rbprops_frfest::ForceWindow>> {
        let taper = self.taper_s.unwrap_or(0.0);
        if !(taper.is_finite() && taper >= 0.0) {
            bail!("{} = {taper}: must be ≥ 0 s", key.at("taper_s"));
        }
        let mut window = match &self.force_window {
            None => default,
            Some(PairOrName::Name(w)) if w == "none" => None,
            Some(PairOrName::Name(w)) => {
                bail!(
                    "{} = \"{w}\": [PRE, POST] in seconds, or \"none\"",
                    key.at("force_window")
                )
            }
            Some(PairOrName::Seconds([pre, post])) => {
                if !(pre.is_finite() && post.is_finite() && *pre >= 0.0 && *post >= 0.0) {
                    bail!(
                        "{} = [{pre}, {post}]: times must be ≥ 0",
                        key.at("force_window")
                    );
                }
                Some(rbprops_frfest::ForceWindow {
                    pre_s: *pre,
                    post_s: *post,
                    taper_s: 0.0,
                })
            }
        };
        if let Some(w) = &mut window {
            w.taper_s = taper;
        } else if self.taper_s.is_some() {
            bail!(
                "{}: there is no force window to taper (force_window = \"none\")",
                key.at("taper_s")
            );
        }
        Ok(window)
    }

    /// How hits are found and judged: trigger, throughput record lengths, ADC ranges and
    /// the fewest hits.
    fn hit_checks(&self, key: Key, o: &mut crate::frf_est::EstimationOptions) -> Result<()> {
        if let Some(t) = self.trigger {
            if !(t > 0.0 && t < 1.0) {
                bail!(
                    "{} = {t}: a fraction of the largest |force| in (0, 1)",
                    key.at("trigger")
                );
            }
            o.trigger = rbprops_frfest::TriggerLevel::FractionOfMax(t);
        }
        o.pretrigger_s = key.positive(self.pretrigger_s, "pretrigger_s")?;
        o.record_s = key.positive(self.record_s, "record_s")?;
        o.force_range = key.positive(self.force_range, "force_range")?;
        o.response_range = key.positive(self.response_range, "response_range")?;
        if let Some(n) = self.min_hits {
            if n < 2 {
                bail!(
                    "{} = {n}: at least 2 hits are needed for a variance",
                    key.at("min_hits")
                );
            }
            o.min_hits = n;
        }
        Ok(())
    }

    /// `force_dof`: each `NODE:DIR` parsed.
    fn force_dofs(&self, key: Key) -> Result<Vec<(i64, i64)>> {
        let mut dofs = Vec::new();
        for d in self.force_dof.iter().flatten() {
            let parsed = d.split_once(':').and_then(|(node, dir)| {
                Some((
                    node.trim().parse::<i64>().ok()?,
                    rbprops_uff::dof::parse_direction(dir)?,
                ))
            });
            match parsed {
                Some(dof) => dofs.push(dof),
                None => bail!(
                    "{} = \"{d}\": NODE:DIR with DIR ±X, ±Y, ±Z or ±1..±3 (e.g. \"201:-X\")",
                    key.at("force_dof")
                ),
            }
        }
        Ok(dofs)
    }
}

/// A key of a campaign file's `[frf_est]` table, named in errors as `FILE: [frf_est] KEY`.
#[derive(Clone, Copy)]
struct Key<'a>(&'a str);

impl Key<'_> {
    fn at(self, key: &str) -> String {
        format!("{}: [frf_est] {key}", self.0)
    }

    /// A value that must be a positive number when given.
    fn positive(self, v: Option<f64>, key: &str) -> Result<Option<f64>> {
        match v {
            Some(x) if !(x.is_finite() && x > 0.0) => {
                bail!("{} = {x}: must be a positive number", self.at(key))
            }
            v => Ok(v),
        }
    }
}

/// `nominal = "spec.toml"` or a table `glob = "spec.toml"`.
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
pub enum NominalConfig {
    /// One nominal spec for every recording.
    One(PathBuf),
    /// A nominal spec per recording, by glob on its path relative to the campaign directory.
    ByGlob(BTreeMap<String, PathBuf>),
}

/// A nominal spec, loaded and validated once.
#[derive(Debug, Clone)]
pub struct Nominal {
    /// The spec's path.
    pub path: PathBuf,
    /// The spec, parsed and validated.
    pub spec: CampaignSpec,
}

/// The options of one campaign run, resolved (files read, values checked).
#[derive(Debug, Clone, Default)]
pub struct CampaignOptions {
    /// The modal fit's options.
    pub fit: rbprops_modal::FitOptions,
    /// How standard errors are obtained.
    pub uncertainty: crate::stages::Uncertainty,
    /// Time constant τ (s) of the exponential window, when one was used.
    pub window_time_constant_s: Option<f64>,
    /// (glob, spec) in the file's order; a single spec has the glob `**`.
    pub nominal: Vec<(String, Nominal)>,
    /// The model check's options (screened effects).
    pub check: rbprops_check::CheckOptions,
    /// UFF file with the nodes and coordinate systems of recordings that carry only datasets 58.
    pub geometry: Option<PathBuf>,
    /// How time-history exports are made into FRFs (`[frf_est]`; frf-est's defaults without).
    pub estimation: crate::frf_est::EstimationOptions,
    /// `averages`: the averages behind FRF exports with coherence.
    pub averages: Option<usize>,
    /// Files the options name (excluded from the items).
    pub named_files: Vec<PathBuf>,
}

impl CampaignConfig {
    /// Reads a campaign file.
    pub fn read(path: &Path) -> Result<CampaignConfig> {
        let text = crate::read_text(path)?;
        toml::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()))
    }

    /// Checks the values and reads the files the options name (relative to `base`).
    /// `uncertainty` (the command line's) takes precedence over the file's.
    pub fn resolve(
        &self,
        base: &Path,
        source: &str,
        uncertainty: Option<crate::stages::UncertaintyChoice>,
    ) -> Result<CampaignOptions> {
        let mut o = CampaignOptions {
            uncertainty: uncertainty
                .or(self.uncertainty)
                .unwrap_or_default()
                .with_defaults(),
            ..Default::default()
        };
        if let Some([a, b]) = self.band_hz {
            if !(a.is_finite() && b.is_finite() && a >= 0.0 && b > a) {
                bail!("{source}: band_hz = [{a}, {b}]: need 0 ≤ FMIN < FMAX");
            }
            o.fit.band_hz = Some((a, b));
        }
        if let Some(m) = &self.method {
            o.fit.method = m.parse().map_err(|e| anyhow!("{source}: method: {e}"))?;
        }
        if let Some(n) = self.modes {
            crate::args::modes(&n.to_string()).map_err(|e| anyhow!("{source}: modes: {e}"))?;
            o.fit.n_modes = Some(n);
        }
        o.fit
            .validate()
            .map_err(|e| anyhow!("{source}: fit options: {e}"))?;
        if let Some(tau) = self.window_time_constant_s {
            if !(tau.is_finite() && tau > 0.0) {
                bail!("{source}: window_time_constant_s = {tau}: must be positive and finite");
            }
            o.window_time_constant_s = Some(tau);
        }
        let load = |p: &Path| -> Result<Nominal> {
            let path = base.join(p);
            let text = crate::read_text(&path)?;
            let spec = CampaignSpec::from_toml_str(&text).map_err(|e| {
                anyhow!(
                    "{}: nominal spec: {e}{}",
                    path.display(),
                    crate::init_spec::placeholder_hint(&text)
                )
            })?;
            Ok(Nominal { path, spec })
        };
        match &self.nominal {
            None => {}
            Some(NominalConfig::One(p)) => o.nominal.push(("**".into(), load(p)?)),
            Some(NominalConfig::ByGlob(map)) => {
                if map.is_empty() {
                    bail!("{source}: [nominal] is empty: give `glob = \"spec.toml\"` entries");
                }
                for (g, p) in map {
                    o.nominal.push((g.clone(), load(p)?));
                }
            }
        }
        o.named_files
            .extend(o.nominal.iter().map(|(_, n)| n.path.clone()));
        if let Some(only) = &self.check_only {
            if o.nominal.is_empty() {
                bail!("{source}: check_only needs a nominal spec (`nominal = \"spec.toml\"`)");
            }
            if only.is_empty() {
                bail!("{source}: check_only is empty: name effect ids, or leave it out to screen them all");
            }
            o.check.only = Some(only.clone());
        }
        if let Some(g) = &self.geometry {
            let g = base.join(g);
            if !g.is_file() {
                bail!("{source}: geometry = {}: no such file", g.display());
            }
            o.named_files.push(g.clone());
            o.geometry = Some(g);
        }
        if let Some(f) = &self.frf_est {
            o.estimation = f.options(source)?;
        }
        if let Some(n) = self.averages {
            crate::args::averages(&n.to_string())
                .map_err(|e| anyhow::anyhow!("{source}: averages = {n}: {e}"))?;
            o.averages = Some(n);
        }
        Ok(o)
    }
}

impl CampaignOptions {
    /// The nominal spec of a recording at `rel` (path relative to the campaign
    /// directory): `None` without model check; an error when no glob or several match.
    pub fn nominal_for(&self, rel: &str) -> Result<Option<&Nominal>> {
        if self.nominal.is_empty() {
            return Ok(None);
        }
        let hits: Vec<&(String, Nominal)> = self
            .nominal
            .iter()
            .filter(|(g, _)| glob_match(g, rel))
            .collect();
        match hits.as_slice() {
            [(_, n)] => Ok(Some(n)),
            [] => bail!(
                "no [nominal] pattern matches '{rel}' (patterns: {})",
                self.nominal
                    .iter()
                    .map(|(g, _)| g.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
            many => bail!(
                "several [nominal] patterns match '{rel}': {} (make them exclusive)",
                many.iter()
                    .map(|(g, _)| g.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
}

/// Glob match on a relative path with `/` separators: `*` any characters but `/`, `**`
/// any characters, `?` one character but `/`.
pub fn glob_match(pattern: &str, path: &str) -> bool {
    fn go(p: &[char], s: &[char]) -> bool {
        if p.starts_with(&['*', '*']) {
            let rest = &p[2..];
            // `**/` also matches nothing, its slash included (`**/*.uff` matches `a.uff`).
            if rest.first() == Some(&'/') && go(&rest[1..], s) {
                return true;
            }
            return (0..=s.len()).any(|k| go(rest, &s[k..]));
        }
        match p.split_first() {
            None => s.is_empty(),
            Some(('*', rest)) => (0..=s.len())
                .take_while(|&k| k == 0 || s[k - 1] != '/')
                .any(|k| go(rest, &s[k..])),
            Some(('?', rest)) => s.first().is_some_and(|&c| c != '/') && go(rest, &s[1..]),
            Some((c, rest)) => s.first() == Some(c) && go(rest, &s[1..]),
        }
    }
    let p: Vec<char> = pattern.chars().collect();
    let s: Vec<char> = path.chars().collect();
    go(&p, &s)
}

/// Finds specs (`*.toml`) and recordings (`*.mcap`, CSV run directories, UFF files) under
/// `dir`, sorted by path so the summary order does not depend on the file system. The
/// campaign file and the files it names (nominal specs, geometry) are not items.
pub fn discover(dir: &Path, exclude: &[PathBuf]) -> Result<Vec<Item>> {
    let exclude: Vec<PathBuf> = exclude
        .iter()
        .filter_map(|p| std::fs::canonicalize(p).ok())
        .collect();
    let mut out = Vec::new();
    walk(dir, &exclude, &mut out).with_context(|| dir.display().to_string())?;
    out.sort();
    Ok(out)
}

fn walk(dir: &Path, exclude: &[PathBuf], out: &mut Vec<Item>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        if std::fs::canonicalize(&p).is_ok_and(|c| exclude.contains(&c)) {
            continue;
        }
        if p.is_dir() {
            if p.join("manifest.csv").exists() {
                out.push(Item::Recording(p));
            } else {
                walk(&p, exclude, out)?;
            }
        } else if p.file_name().is_some_and(|n| n == CONFIG_FILE) {
            continue;
        } else if is_uff(&p) {
            out.push(Item::Recording(p));
        } else {
            match p.extension().and_then(|e| e.to_str()) {
                Some("toml") => out.push(Item::Spec(p)),
                Some("mcap") => out.push(Item::Recording(p)),
                _ => {}
            }
        }
    }
    Ok(())
}

/// The model check's verdict columns of a summary row.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CheckColumns {
    /// Accepted effect ids, then ambiguous families as `a/b`, space separated.
    pub effects: String,
    /// `χ²/ν` of the nominal model on the recording (docs/conventions.md §8).
    pub chi2_nu_nominal: f64,
    /// `χ²/ν` before the accepted effects: the nominal model with its fitted nuisance parameters.
    pub chi2_nu_before: f64,
    /// `χ²/ν` with the accepted effects.
    pub chi2_nu_after: f64,
    /// True when the final residual is at the data's noise floor.
    pub noise_floor_reached: bool,
    /// The check's verdict in words (`error: …` when it failed).
    pub verdict: String,
    /// The verdict as a short label for tables ([`check_label`]; [`CHECK_FAILED`] when
    /// the check failed).
    pub label: String,
}

/// The label of a model check that could not run.
pub const CHECK_FAILED: &str = "check failed";

/// A model check's verdict as a short label for a table row: `clean, at the noise floor`,
/// or each effect found with its largest fitted quantity (`channel_gain channel 103y:
/// gain +6.0 %`), ambiguous families as `one of a/b`, and whether the residual then
/// reaches the noise. The full verdict (with what the test cannot see) is in the
/// recording's section.
pub fn check_label(r: &rbprops_check::ModelCheckReport) -> String {
    let floor = if r.noise_floor_reached {
        "at the noise floor"
    } else {
        "above the noise floor"
    };
    if r.accepted.is_empty() && r.ambiguous.is_empty() {
        return format!("clean, {floor}");
    }
    let mut parts: Vec<String> = r
        .accepted
        .iter()
        .map(|a| {
            // The quantity furthest from zero relative to its plausible range.
            let rel = |v: f64, range: [f64; 2]| {
                v.abs() / (range[1] - range[0]).abs().max(f64::MIN_POSITIVE)
            };
            let top = a
                .plausible
                .iter()
                .max_by(|x, y| rel(x.value, x.range).total_cmp(&rel(y.value, y.range)));
            match top {
                Some(p) => format!("{} {} {:+.3} {}", a.id, p.quantity, p.value, p.unit),
                None => a.id.clone(),
            }
        })
        .collect();
    parts.extend(
        r.ambiguous
            .iter()
            .map(|f| format!("one of {}", f.ids.join("/"))),
    );
    parts.push(floor.to_string());
    parts.join("; ")
}

/// The model check of a recording against its nominal spec (with the campaign's known
/// exponential window added as a known effect, unless the spec has one).
pub fn model_check(
    recording: &str,
    geometry: &rbprops_core::Geometry,
    frf: &rbprops_core::FrfSet,
    nominal: &Nominal,
    window_time_constant_s: Option<f64>,
    options: &rbprops_check::CheckOptions,
) -> Result<(CheckColumns, rbprops_check::CheckOutcome)> {
    let mut spec = nominal.spec.clone();
    if let Some(sigma) = window_time_constant_s.map(|tau| 1.0 / tau) {
        if !spec.effects.iter().any(|e| e.id == ExponentialWindow::ID) {
            let mut parameters = toml::Table::new();
            parameters.insert("decay_per_s".into(), sigma.into());
            spec.effects.push(rbprops_sim::spec::EffectSpec {
                id: ExponentialWindow::ID.into(),
                parameters,
            });
        }
    }
    let out = rbprops_check::check(&spec, geometry, frf, options)
        .map_err(|e| crate::init_spec::mismatch_hint(e, recording))
        .with_context(|| format!("model check against {}", nominal.path.display()))?;
    let r = &out.report;
    let mut effects: Vec<String> = r.accepted.iter().map(|a| a.id.clone()).collect();
    effects.extend(r.ambiguous.iter().map(|f| f.ids.join("/")));
    let columns = CheckColumns {
        effects: effects.join(" "),
        chi2_nu_nominal: r.chi2_nu_nominal,
        chi2_nu_before: r.chi2_nu_before,
        chi2_nu_after: r.chi2_nu_after,
        noise_floor_reached: r.noise_floor_reached,
        verdict: r.verdict.clone(),
        label: check_label(r),
    };
    Ok((columns, out))
}

/// Name of the run file in an item's output directory (see [`run_all`]'s `runs`).
pub const RUN_FILE: &str = "run.mcap";

/// The output directory of the item labelled `rel` under `runs`: the label made
/// file-name safe (`sub/run-01.uff` → `sub_run-01_uff`).
pub fn run_dir(runs: &Path, rel: &str) -> PathBuf {
    runs.join(crate::plots::sanitize(rel))
}

/// A recording item read as the campaign reads it: the campaign's geometry file for its
/// UFF exports, `[frf_est]` for time histories, and `averages` for an FRF export with
/// coherence and no line variances.
pub fn read_recording(p: &Path, opts: &CampaignOptions) -> Result<crate::Input> {
    let uff = crate::UffInputOptions {
        geometry: opts.geometry.clone().filter(|_| is_uff(p)),
        channels: None,
        estimation: opts.estimation.clone(),
    };
    let checks = crate::InputChecks::default();
    let mut inp = crate::read_stage_input_quiet("read", Some(p), &checks, &uff)?;
    let without_variance = inp
        .record
        .topic(rbprops_formats::topics::FRF_VARIANCE)
        .is_none();
    if without_variance && crate::coherence::get(&inp.record)?.is_some() {
        let source = p.display().to_string();
        crate::variance::declare_averages(&mut inp.record, opts.averages, &source)?;
    }
    Ok(inp)
}

/// Runs one item through the pipeline with the campaign's options. `rel` is the item's
/// path relative to the campaign directory (its label and the key of the nominal globs).
///
/// With `runs`, the item's final record (every stage's topic, the model check's report
/// included) is written to `runs/<label>/run.mcap` with its figures beside it (FRF fit
/// panels, stabilisation diagrams, NI and MIF curves, estimates with 95 % error bars,
/// the model check's residual maps and worst channels): what `rbprops report` reads.
pub fn run_item(
    item: &Item,
    rel: &str,
    opts: &CampaignOptions,
    runs: Option<&Path>,
) -> Result<(Vec<SummaryRow>, Vec<crate::warnings::Diagnostic>)> {
    let mut read_warnings = Vec::new();
    let (mut rec, sha) = match item {
        Item::Spec(p) => {
            let text = crate::read_text(p)?;
            let (rec, _) = crate::stages::simulate(&text, &p.display().to_string(), None)?;
            let sha = rbprops_formats::sha256_hex(&rbprops_formats::mcap_file::write(&rec)?);
            (rec, sha)
        }
        Item::Recording(p) => {
            let inp = read_recording(p, opts)?;
            read_warnings = inp.warnings;
            (inp.record, inp.sha256)
        }
    };
    let name = item.path().display().to_string();
    let nominal = opts.nominal_for(rel).with_context(|| name.clone())?;
    let recorded = match nominal {
        Some(_) => Some(
            rec.require_geometry_and_frf()
                .with_context(|| name.clone())?,
        ),
        None => None,
    }
    .map(|(g, f)| (g, f.clone()));
    let fit =
        crate::stages::modal_fit_windowed(&mut rec, &opts.fit, opts.window_time_constant_s, &sha)
            .with_context(|| name.clone())?;
    let selection = crate::stages::ni_select(&mut rec, &Default::default(), &sha)
        .with_context(|| name.clone())?;
    crate::stages::rb_solve_with(&mut rec, &Default::default(), &opts.uncertainty, true, &sha)
        .with_context(|| name.clone())?;
    let mut rows = summary::rows(&rec, rel, "ni", "geometry")?;
    let mut check_figures = Vec::new();
    if let (Some(n), Some((g, f))) = (nominal, recorded) {
        let c = match model_check(&name, &g, &f, n, opts.window_time_constant_s, &opts.check) {
            Ok((c, outcome)) => {
                if runs.is_some() {
                    rec.set(
                        rbprops_formats::topics::MODEL_CHECK,
                        std::slice::from_ref(&outcome.report),
                    );
                    check_figures = crate::plots::model_check(&outcome, &g)?;
                }
                c
            }
            Err(e) => CheckColumns {
                verdict: format!("error: {e:#}"),
                label: CHECK_FAILED.into(),
                ..Default::default()
            },
        };
        for r in &mut rows {
            r.set_check(&c);
        }
    }
    if let Some(runs) = runs {
        let dir = run_dir(runs, rel);
        let (geometry, frf) = rec.require_geometry_and_frf()?;
        let mut figures = crate::plots::modal_fit(&geometry, frf, &fit)?;
        figures.extend(crate::plots::indicators(&selection)?);
        // The record's estimates: the bootstrap's standard errors when it ran.
        let estimates: Vec<rbprops_core::records::InertiaEstimate> =
            rec.get(rbprops_formats::topics::ESTIMATES)?;
        figures.extend(crate::plots::estimates(&estimates)?);
        figures.extend(check_figures);
        crate::write_plots(&dir, &figures)?;
        rbprops_formats::write_path(&rec, &dir.join(RUN_FILE))?;
    }
    let mut warnings = crate::warnings::Collector::default();
    for d in read_warnings {
        warnings.add_from("read", d);
    }
    warnings.extend(crate::warnings::from_record(&rec)?);
    Ok((rows, warnings.items))
}

/// What one item gave: its summary rows and its diagnostics (subject: its label).
#[derive(Debug, Clone)]
pub struct ItemOutcome {
    /// The item's summary rows (one row with method `error` when its pipeline failed).
    pub rows: Vec<SummaryRow>,
    /// The item's diagnostics, each naming the item's label as its recording.
    pub warnings: Vec<crate::warnings::Diagnostic>,
}

impl ItemOutcome {
    /// True when the item's pipeline failed (one row with method `error`).
    pub fn failed(&self) -> bool {
        self.rows.len() == 1 && self.rows[0].method == "error"
    }

    /// True when the item's model check failed.
    pub fn check_failed(&self) -> bool {
        self.rows
            .first()
            .is_some_and(|r| r.check_label == CHECK_FAILED)
    }
}

/// The outcome of a campaign: rows in item order and the failures counted.
pub struct CampaignResult {
    /// One summary row per estimate of every item.
    pub rows: Vec<SummaryRow>,
    /// Every item's diagnostics, each naming the item's label as its recording, in item order.
    pub warnings: crate::warnings::Collector,
    /// Items whose pipeline failed (one row with method `error`).
    pub failed: usize,
    /// Items whose model check failed (their verdict starts with `error:`).
    pub checks_failed: usize,
}

impl CampaignResult {
    /// The campaign's outcome from its items' outcomes, in item order.
    pub fn from_outcomes(outcomes: Vec<ItemOutcome>) -> CampaignResult {
        let mut warnings = crate::warnings::Collector::default();
        for w in outcomes.iter().flat_map(|o| &o.warnings) {
            warnings.add(w.clone());
        }
        let failed = outcomes.iter().filter(|o| o.failed()).count();
        let checks_failed = outcomes.iter().filter(|o| o.check_failed()).count();
        CampaignResult {
            rows: outcomes.into_iter().flat_map(|o| o.rows).collect(),
            warnings,
            failed,
            checks_failed,
        }
    }
}

/// The label of an item: its path relative to the campaign directory `root`, with `/`
/// separators (the summary's `campaign` column and the key of the nominal globs).
pub fn label(item: &Item, root: &Path) -> String {
    item.path()
        .strip_prefix(root)
        .unwrap_or(item.path())
        .to_string_lossy()
        .replace(std::path::MAIN_SEPARATOR, "/")
}

/// Runs every item in parallel (with `runs`, each item's record and figures are written
/// under it: see [`run_item`]). A failed item becomes one row with method `error` and the
/// message in its `warnings` column, so the table still accounts for every input.
/// Outcomes come out in item order whatever the thread count.
pub fn run_items(
    items: &[Item],
    root: &Path,
    opts: &CampaignOptions,
    runs: Option<&Path>,
    progress: &indicatif::ProgressBar,
) -> Vec<ItemOutcome> {
    items
        .par_iter()
        .map(|item| {
            let rel = label(item, root);
            let (rows, mut warnings) = run_item(item, &rel, opts, runs).unwrap_or_else(|e| {
                let row = SummaryRow {
                    campaign: rel.clone(),
                    set: "ni".into(),
                    origin: "geometry".into(),
                    method: "error".into(),
                    warnings: format!("{e:#}"),
                    ..Default::default()
                };
                (vec![row], Vec::new())
            });
            for d in &mut warnings {
                d.subject.recording = Some(rel.clone());
            }
            progress.inc(1);
            ItemOutcome { rows, warnings }
        })
        .collect()
}

/// Runs every item ([`run_items`]) and gathers the outcomes in item order.
pub fn run_all(
    items: &[Item],
    root: &Path,
    opts: &CampaignOptions,
    runs: Option<&Path>,
    progress: &indicatif::ProgressBar,
) -> CampaignResult {
    CampaignResult::from_outcomes(run_items(items, root, opts, runs, progress))
}

#[cfg(test)]
mod tests {
    use super::glob_match;

    #[test]
    fn globs() {
        assert!(glob_match("*.uff", "a.uff"));
        assert!(!glob_match("*.uff", "sub/a.uff"));
        assert!(glob_match("**", "sub/a.uff"));
        assert!(glob_match("**/*.uff", "sub/deep/a.uff"));
        assert!(glob_match("**/*.uff", "a.uff"));
        assert!(glob_match("sub/*.uff", "sub/a.uff"));
        assert!(glob_match("run-??.58", "run-07.58"));
        assert!(!glob_match("run-??.58", "run-7.58"));
        assert!(!glob_match("a.uff", "b.uff"));
        assert!(glob_match("rig-a/**", "rig-a/x/y.uff"));
        assert!(!glob_match("rig-a/**", "rig-b/x.uff"));
    }
}
