//! A campaign split over machines: `rbprops campaign DIR --shard K/N -o SHARD` runs one
//! share of the items, and `rbprops campaign merge SHARD… -o OUT` puts the shares back
//! together, byte for byte what one `rbprops campaign DIR -o OUT/summary.csv
//! [--runs OUT/runs]` writes.
//!
//! **Partition.** The campaign's items in their summary order (the order of
//! [`campaign::discover`]: specs, then recordings, each sorted by path) are numbered
//! i = 0, 1, …; item i belongs to shard K of N when `i mod N = K − 1` (round robin). Every
//! machine lists the same items, so every task of a job array picks its share without
//! talking to the others, the shares differ by at most one item, and neighbouring items
//! (often of similar cost: one folder, one rig) are spread over the shards. The merge
//! never depends on the partition: it puts each item's rows back at the item's number.
//! Adding or removing an item renumbers those after it, so a changed campaign is run
//! again on every shard; the merge refuses shards of different item lists.
//!
//! **A shard's directory.** `summary.csv` (the shard's rows, a summary table of its own),
//! `runs/` (with `--runs SHARD/runs`: each of its items' run and figures) and
//! [`CAMPAIGN_MANIFEST`]: the campaign's identity (directory as given, the whole item
//! list, the options) and, per item of the shard, its rows as summary CSV lines, its
//! warnings and whether it failed. The merge reads the manifests only (and checks each
//! shard's `summary.csv` against its manifest).

use crate::campaign::{self, CampaignOptions, Item, ItemOutcome};
use crate::warnings::{Collector, Diagnostic};
use anyhow::{anyhow, bail, Context, Result};
use rbprops_formats::atomic::CAMPAIGN_MANIFEST;
use rbprops_formats::FormatError;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// The `format` of a shard's manifest.
pub const SHARD_FORMAT: &str = "rbprops campaign shard 2";
/// The `format` of a merged campaign's manifest.
pub const MERGED_FORMAT: &str = "rbprops campaign merge 1";
/// The summary table in a shard's or merged campaign's directory.
pub const SUMMARY_FILE: &str = "summary.csv";
/// The items' runs and figures in a shard's or merged campaign's directory.
pub const RUNS_DIR: &str = "runs";

/// Shard `k` of `n` (1 ≤ k ≤ n), written `K/N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// This shard's number, 1-based (a job array's task id).
    pub k: usize,
    /// The number of shards.
    pub n: usize,
}

impl FromStr for Shard {
    type Err = String;

    fn from_str(s: &str) -> Result<Shard, String> {
        let (k, n) = s
            .split_once('/')
            .ok_or_else(|| format!("'{s}': expected K/N, e.g. 3/8 (shard 3 of 8)"))?;
        let number = |t: &str, what: &str| -> Result<usize, String> {
            t.trim()
                .parse::<usize>()
                .map_err(|_| format!("'{s}': {what} '{t}' is not a whole number"))
        };
        let (k, n) = (number(k, "K")?, number(n, "N")?);
        if n == 0 || k == 0 || k > n {
            return Err(format!("'{s}': need 1 ≤ K ≤ N"));
        }
        Ok(Shard { k, n })
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

impl Shard {
    /// True when item `i` (0-based, in the campaign's item order) is this shard's:
    /// `i mod N = K − 1`.
    pub fn holds(&self, i: usize) -> bool {
        i % self.n == self.k - 1
    }

    /// This shard's item numbers among `len` items, in order.
    pub fn indices(&self, len: usize) -> Vec<usize> {
        (self.k - 1..len).step_by(self.n).collect()
    }
}

/// What makes two shards parts of one campaign: the same directory (as given on the
/// command line: it appears in the items' error messages), the same items and the same
/// options. Recorded in every shard's manifest and compared by the merge.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct CampaignIdentity {
    /// The campaign directory as given.
    pub campaign_dir: String,
    /// Every item's label (path relative to the campaign directory), in item order.
    pub items: Vec<String>,
    /// The options in effect, one line each ([`options_description`]).
    pub options: Vec<String>,
    /// True when the items' runs and figures were written (`--runs`).
    pub runs: bool,
    /// True when the campaign has a model check (a nominal spec).
    pub model_check: bool,
}

impl CampaignIdentity {
    /// The identity of the campaign of `items` under `root` (given as `dir`) with `opts`.
    pub fn new(dir: &Path, items: &[Item], opts: &CampaignOptions, runs: bool) -> Result<Self> {
        Ok(CampaignIdentity {
            campaign_dir: dir.display().to_string(),
            items: items.iter().map(|i| campaign::label(i, dir)).collect(),
            options: options_description(opts)?,
            runs,
            model_check: !opts.nominal.is_empty(),
        })
    }
}

/// The options that decide a campaign's output, one line each: the program's version,
/// the modal fit's, uncertainty, window and model-check options as resolved, and the
/// path and SHA-256 of every file the campaign file names (nominal specs, geometry).
pub fn options_description(opts: &CampaignOptions) -> Result<Vec<String>> {
    let sha = |p: &Path| -> Result<String> {
        let bytes = std::fs::read(p).with_context(|| p.display().to_string())?;
        Ok(rbprops_formats::sha256_hex(&bytes))
    };
    let mut lines = vec![
        format!("rbprops {}", env!("CARGO_PKG_VERSION")),
        format!("fit: {:?}", opts.fit),
        format!("uncertainty: {:?}", opts.uncertainty),
        format!("window_time_constant_s: {:?}", opts.window_time_constant_s),
        format!("check: {:?}", opts.check),
        format!("frf_est: {:?}", opts.estimation),
    ];
    for (glob, n) in &opts.nominal {
        lines.push(format!(
            "nominal {glob}: {} sha256 {}",
            n.path.display(),
            sha(&n.path)?
        ));
    }
    if let Some(g) = &opts.geometry {
        lines.push(format!("geometry: {} sha256 {}", g.display(), sha(g)?));
    }
    Ok(lines)
}

/// One item's outcome as a shard records it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ItemRecord {
    /// The item's number in the campaign's item order (0-based).
    pub index: usize,
    /// The item's label.
    pub label: String,
    /// How many summary rows it gave.
    pub rows: usize,
    /// Its rows as summary CSV lines (no header), exactly as the whole table holds them.
    pub csv: String,
    /// True when its pipeline failed (one row with method `error`).
    pub failed: bool,
    /// True when its model check failed.
    pub check_failed: bool,
    /// Its diagnostics, each naming its label as the recording.
    pub warnings: Vec<Diagnostic>,
}

/// The manifest of a shard's (or a merged campaign's) directory.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// [`SHARD_FORMAT`] or [`MERGED_FORMAT`].
    pub format: String,
    /// This shard's number K (none for a merged campaign).
    pub shard: Option<usize>,
    /// The number of shards N.
    pub shards: usize,
    /// The campaign.
    #[serde(flatten)]
    pub campaign: CampaignIdentity,
    /// The shard's items' outcomes in item order (empty for a merged campaign).
    pub results: Vec<ItemRecord>,
}

/// The summary CSV header line (with its newline).
fn csv_header() -> Result<String> {
    let text = crate::summary::to_csv(&[Default::default()])?;
    let end = text.find('\n').map_or(text.len(), |e| e + 1);
    Ok(text[..end].to_string())
}

/// The rows' summary CSV lines without the header: what the rows add to a whole table.
fn csv_body(rows: &[crate::summary::SummaryRow]) -> Result<String> {
    let text = crate::summary::to_csv(rows)?;
    Ok(match text.find('\n') {
        Some(e) => text[e + 1..].to_string(),
        None => String::new(),
    })
}

/// A summary table from item bodies: `to_csv` of all their rows (empty without rows).
fn summary_text<'a>(bodies: impl IntoIterator<Item = &'a ItemRecord>) -> Result<String> {
    let body: String = bodies.into_iter().map(|r| r.csv.as_str()).collect();
    Ok(if body.is_empty() {
        String::new()
    } else {
        csv_header()? + &body
    })
}

fn record(index: usize, label: String, o: &ItemOutcome) -> Result<ItemRecord> {
    Ok(ItemRecord {
        index,
        label,
        rows: o.rows.len(),
        csv: csv_body(&o.rows)?,
        failed: o.failed(),
        check_failed: o.check_failed(),
        warnings: o.warnings.clone(),
    })
}

fn to_format_error(path: &Path, e: anyhow::Error) -> FormatError {
    FormatError::other(&path.display().to_string(), format!("{e:#}"))
}

fn write_json(path: &Path, m: &Manifest) -> Result<(), FormatError> {
    let text = serde_json::to_string_pretty(m)
        .map_err(|e| FormatError::other(&path.display().to_string(), e))?;
    std::fs::write(path, text + "\n").map_err(|e| FormatError::Io {
        file: path.display().to_string(),
        source: e,
    })
}

fn write_plain(path: &Path, text: &str) -> Result<(), FormatError> {
    std::fs::write(path, text).map_err(|e| FormatError::Io {
        file: path.display().to_string(),
        source: e,
    })
}

/// True when `inner` is `outer` or lies under it (paths made absolute, symbolic links
/// resolved as far as they exist).
fn is_within(inner: &Path, outer: &Path) -> bool {
    let resolve = |p: &Path| -> PathBuf {
        let abs = std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        // Resolve the longest existing ancestor, keep the rest as written.
        let mut head = abs.clone();
        let mut tail = Vec::new();
        while !head.exists() {
            match (head.parent(), head.file_name()) {
                (Some(parent), Some(name)) => {
                    tail.push(name.to_os_string());
                    head = parent.to_path_buf();
                }
                _ => return abs,
            }
        }
        let mut out = std::fs::canonicalize(&head).unwrap_or(head);
        for t in tail.into_iter().rev() {
            out.push(t);
        }
        out
    };
    resolve(inner).starts_with(resolve(outer))
}

/// Checks a shard's output paths: `out` outside the campaign directory (else its files
/// would be items of the next run) and the runs, when asked for, at `out/runs`.
pub fn check_shard_paths(dir: &Path, out: &Path, runs: Option<&Path>) -> Result<()> {
    if is_within(out, dir) {
        bail!(
            "-o {}: inside the campaign directory {}: the next run would read the shard's files as items; write shards elsewhere",
            out.display(),
            dir.display()
        );
    }
    if let Some(r) = runs {
        if !(is_within(r, &out.join(RUNS_DIR)) && is_within(&out.join(RUNS_DIR), r)) {
            bail!(
                "--runs {}: a shard keeps its runs in its own directory: give --runs {}",
                r.display(),
                out.join(RUNS_DIR).display()
            );
        }
    }
    Ok(())
}

/// Runs shard `shard` of the campaign (`items` under `dir`, identity `id`) and writes its
/// directory `out` (atomically: nothing is left there on failure). Returns the shard's
/// outcome (its items only), for the caller's warnings and counts.
pub fn run_shard(
    shard: Shard,
    dir: &Path,
    items: &[Item],
    opts: &CampaignOptions,
    id: CampaignIdentity,
    out: &Path,
    progress: &indicatif::ProgressBar,
) -> Result<campaign::CampaignResult> {
    let indices = shard.indices(items.len());
    progress.set_length(indices.len() as u64);
    let mine: Vec<Item> = indices.iter().map(|&i| items[i].clone()).collect();
    let mut result = None;
    rbprops_formats::atomic::write_dir(out, |tmp| {
        let runs = id.runs.then(|| tmp.join(RUNS_DIR));
        if let Some(r) = &runs {
            std::fs::create_dir_all(r).map_err(|e| FormatError::Io {
                file: r.display().to_string(),
                source: e,
            })?;
        }
        let outcomes = campaign::run_items(&mine, dir, opts, runs.as_deref(), progress);
        let results = indices
            .iter()
            .zip(&outcomes)
            .map(|(&i, o)| record(i, id.items[i].clone(), o))
            .collect::<Result<Vec<_>>>()
            .map_err(|e| to_format_error(out, e))?;
        let summary = summary_text(&results).map_err(|e| to_format_error(out, e))?;
        write_plain(&tmp.join(SUMMARY_FILE), &summary)?;
        let manifest = Manifest {
            format: SHARD_FORMAT.into(),
            shard: Some(shard.k),
            shards: shard.n,
            campaign: id,
            results,
        };
        write_json(&tmp.join(CAMPAIGN_MANIFEST), &manifest)?;
        result = Some(campaign::CampaignResult::from_outcomes(outcomes));
        Ok(())
    })?;
    result.ok_or_else(|| anyhow!("{}: the shard was not written", out.display()))
}

/// A shard's directory as the merge reads it.
struct ShardDir {
    dir: PathBuf,
    manifest: Manifest,
}

impl ShardDir {
    fn name(&self) -> String {
        self.dir.display().to_string()
    }

    fn k(&self) -> usize {
        self.manifest.shard.unwrap_or(0)
    }

    fn read(dir: &Path) -> Result<ShardDir> {
        let name = dir.display();
        if !dir.is_dir() {
            bail!("{name}: no such shard directory");
        }
        let path = dir.join(CAMPAIGN_MANIFEST);
        if !path.is_file() {
            bail!(
                "{name}: not a campaign shard (no {CAMPAIGN_MANIFEST}; a shard is written by `rbprops campaign DIR --shard K/N -o {name}`)"
            );
        }
        let text = crate::read_text(&path)?;
        let manifest: Manifest =
            serde_json::from_str(&text).map_err(|e| anyhow!("{}: {e}", path.display()))?;
        if manifest.format == MERGED_FORMAT {
            bail!("{name}: a merged campaign, not a shard: merge the shards it was made from");
        }
        if manifest.format != SHARD_FORMAT {
            bail!(
                "{}: format '{}': expected '{SHARD_FORMAT}' (written by another version of rbprops?)",
                path.display(),
                manifest.format
            );
        }
        let (Some(k), n) = (manifest.shard, manifest.shards) else {
            bail!("{}: no shard number", path.display());
        };
        if k == 0 || k > n {
            bail!("{}: shard {k}/{n}: need 1 ≤ K ≤ N", path.display());
        }
        Ok(ShardDir {
            dir: dir.to_path_buf(),
            manifest,
        })
    }

    /// Checks that the shard holds exactly its share of the items and that its
    /// `summary.csv` is what its manifest records.
    fn check_contents(&self) -> Result<()> {
        let m = &self.manifest;
        let shard = Shard {
            k: self.k(),
            n: m.shards,
        };
        let want = shard.indices(m.campaign.items.len());
        let have: Vec<usize> = m.results.iter().map(|r| r.index).collect();
        if have != want {
            bail!(
                "{}: holds items {have:?}, but shard {shard} of {} items is items {want:?} (the manifest was changed?)",
                self.name(),
                m.campaign.items.len()
            );
        }
        let header = csv_header()?;
        for r in &m.results {
            if r.label != m.campaign.items[r.index] {
                bail!(
                    "{}: item {} is '{}' in its results but '{}' in its item list",
                    self.name(),
                    r.index,
                    r.label,
                    m.campaign.items[r.index]
                );
            }
            let rows = crate::summary::from_csv(&(header.clone() + &r.csv))
                .with_context(|| format!("{}: rows of '{}'", self.name(), r.label))?;
            if rows.len() != r.rows || rows.iter().any(|row| row.campaign != r.label) {
                bail!(
                    "{}: the rows recorded for '{}' are not its own ({} rows recorded, {} read)",
                    self.name(),
                    r.label,
                    r.rows,
                    rows.len()
                );
            }
        }
        let summary_path = self.dir.join(SUMMARY_FILE);
        let summary = crate::read_text(&summary_path)?;
        if summary != summary_text(&m.results)? {
            bail!(
                "{}: differs from the rows its {CAMPAIGN_MANIFEST} records (changed after the shard was written?): run the shard again",
                summary_path.display()
            );
        }
        Ok(())
    }
}

/// The first difference between two campaigns' identities, in words.
fn identity_difference(
    a: &CampaignIdentity,
    b: &CampaignIdentity,
    an: &str,
    bn: &str,
) -> Option<String> {
    if a.campaign_dir != b.campaign_dir {
        return Some(format!(
            "{an} and {bn} are shards of different campaigns: campaign directory '{}' in {an}, '{}' in {bn} (give every shard the same DIR: it appears in the items' messages)",
            a.campaign_dir, b.campaign_dir
        ));
    }
    if a.items != b.items {
        let only = |x: &[String], y: &[String]| x.iter().find(|l| !y.contains(l)).cloned();
        let detail = if let Some(l) = only(&a.items, &b.items) {
            format!("'{l}' is an item in {an} only")
        } else if let Some(l) = only(&b.items, &a.items) {
            format!("'{l}' is an item in {bn} only")
        } else {
            "the same items in a different order".into()
        };
        return Some(format!(
            "{an} and {bn} are shards of different campaigns: {} items in {an}, {} in {bn}; {detail} (the campaign changed between the shards' runs: run every shard again)",
            a.items.len(),
            b.items.len()
        ));
    }
    if a.options != b.options {
        let n = a.options.len().max(b.options.len());
        let none = String::from("(nothing)");
        let (x, y) = (0..n)
            .map(|i| {
                (
                    a.options.get(i).unwrap_or(&none),
                    b.options.get(i).unwrap_or(&none),
                )
            })
            .find(|(x, y)| x != y)
            .unwrap_or((&none, &none));
        return Some(format!(
            "{an} and {bn} were run with different options: '{x}' in {an}, '{y}' in {bn}"
        ));
    }
    if a.runs != b.runs {
        let (with, without) = if a.runs { (an, bn) } else { (bn, an) };
        return Some(format!(
            "{an} and {bn} were run with different options: {with} has its items' runs (--runs), {without} has not"
        ));
    }
    if a.model_check != b.model_check {
        return Some(format!(
            "{an} and {bn} were run with different options: one has a model check, the other not"
        ));
    }
    None
}

/// A merged campaign.
pub struct Merged {
    /// The campaign.
    pub campaign: CampaignIdentity,
    /// The summary table, byte for byte the single run's.
    pub summary: String,
    /// Every item's warnings in item order.
    pub warnings: Collector,
    /// Rows in the table.
    pub rows: usize,
    /// Items whose pipeline failed.
    pub failed: usize,
    /// Items whose model check failed.
    pub checks_failed: usize,
}

/// Reads and checks the shards: every shard of one campaign, split the same way, each
/// once, none missing, each holding exactly its share; errors name the directories.
fn read_shards(dirs: &[PathBuf]) -> Result<Vec<ShardDir>> {
    if dirs.is_empty() {
        bail!("no shard directories given");
    }
    let mut shards = dirs
        .iter()
        .map(|d| ShardDir::read(d))
        .collect::<Result<Vec<_>>>()?;
    let first = &shards[0];
    for s in &shards[1..] {
        if s.manifest.shards != first.manifest.shards {
            bail!(
                "{} is shard {}/{} and {} is shard {}/{}: the shards of one merge split the campaign the same way (same N)",
                first.name(),
                first.k(),
                first.manifest.shards,
                s.name(),
                s.k(),
                s.manifest.shards
            );
        }
        if let Some(d) = identity_difference(
            &first.manifest.campaign,
            &s.manifest.campaign,
            &first.name(),
            &s.name(),
        ) {
            bail!(d);
        }
    }
    let n = first.manifest.shards;
    for (i, a) in shards.iter().enumerate() {
        if let Some(b) = shards[..i].iter().find(|b| b.k() == a.k()) {
            bail!(
                "{} and {} are both shard {}/{n} (overlapping shards: give each shard once)",
                b.name(),
                a.name(),
                a.k()
            );
        }
    }
    let missing: Vec<String> = (1..=n)
        .filter(|k| !shards.iter().any(|s| s.k() == *k))
        .map(|k| format!("{k}/{n}"))
        .collect();
    if !missing.is_empty() {
        bail!(
            "shard{} {} missing (given: {})",
            if missing.len() == 1 { "" } else { "s" },
            missing.join(", "),
            shards
                .iter()
                .map(|s| format!("{} = {}/{n}", s.name(), s.k()))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    for s in &shards {
        s.check_contents()?;
    }
    shards.sort_by_key(|s| s.k());
    Ok(shards)
}

/// Copies the directory `from` (files and subdirectories) to `to`, byte for byte.
fn copy_dir(from: &Path, to: &Path) -> std::io::Result<()> {
    std::fs::create_dir_all(to)?;
    let mut entries: Vec<_> = std::fs::read_dir(from)?.collect::<std::io::Result<_>>()?;
    entries.sort_by_key(|e| e.file_name());
    for e in entries {
        let (src, dst) = (e.path(), to.join(e.file_name()));
        if e.file_type()?.is_dir() {
            copy_dir(&src, &dst)?;
        } else {
            std::fs::copy(&src, &dst)?;
        }
    }
    Ok(())
}

/// Merges shard directories into `out`: `summary.csv` (the rows of every item in item
/// order), `runs/` (when the shards have their items' runs) and a manifest, written
/// atomically. The result holds the counts and warnings the single run would print.
pub fn merge(dirs: &[PathBuf], out: &Path) -> Result<Merged> {
    for d in dirs {
        rbprops_formats::atomic::register_input(d);
    }
    let shards = read_shards(dirs)?;
    let campaign = shards[0].manifest.campaign.clone();
    let mut by_item: Vec<(&ShardDir, &ItemRecord)> = shards
        .iter()
        .flat_map(|s| s.manifest.results.iter().map(move |r| (s, r)))
        .collect();
    by_item.sort_by_key(|(_, r)| r.index);
    let summary = summary_text(by_item.iter().map(|(_, r)| *r))?;
    let mut warnings = Collector::default();
    for w in by_item.iter().flat_map(|(_, r)| &r.warnings) {
        warnings.add(w.clone());
    }
    let merged = Merged {
        summary,
        warnings,
        rows: by_item.iter().map(|(_, r)| r.rows).sum(),
        failed: by_item.iter().filter(|(_, r)| r.failed).count(),
        checks_failed: by_item.iter().filter(|(_, r)| r.check_failed).count(),
        campaign,
    };
    rbprops_formats::atomic::write_dir(out, |tmp| {
        write_plain(&tmp.join(SUMMARY_FILE), &merged.summary)?;
        if merged.campaign.runs {
            let runs = tmp.join(RUNS_DIR);
            std::fs::create_dir_all(&runs).map_err(|e| FormatError::Io {
                file: runs.display().to_string(),
                source: e,
            })?;
            for (s, r) in &by_item {
                let name = crate::plots::sanitize(&r.label);
                let src = s.dir.join(RUNS_DIR).join(&name);
                if src.is_dir() {
                    copy_dir(&src, &runs.join(&name)).map_err(|e| FormatError::Io {
                        file: src.display().to_string(),
                        source: e,
                    })?;
                } else if !r.failed {
                    return Err(FormatError::other(
                        &src.display().to_string(),
                        format!(
                            "missing: shard {} ran '{}' with --runs, but its run is not there",
                            s.name(),
                            r.label
                        ),
                    ));
                }
            }
        }
        let manifest = Manifest {
            format: MERGED_FORMAT.into(),
            shard: None,
            shards: shards.len(),
            campaign: merged.campaign.clone(),
            results: Vec::new(),
        };
        write_json(&tmp.join(CAMPAIGN_MANIFEST), &manifest)
    })?;
    Ok(merged)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shards_parse_and_partition_the_items_once() {
        assert_eq!("3/8".parse::<Shard>(), Ok(Shard { k: 3, n: 8 }));
        for bad in ["0/4", "5/4", "1/0", "3", "a/4", "1/b", "-1/4"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
        for len in [0, 1, 5, 17, 200] {
            for n in 1..=7 {
                let mut seen = vec![0; len];
                for k in 1..=n {
                    let s = Shard { k, n };
                    let idx = s.indices(len);
                    assert!(idx.iter().all(|&i| s.holds(i)));
                    assert!(idx.len() <= len.div_ceil(n) && idx.len() >= len / n);
                    for i in idx {
                        seen[i] += 1;
                    }
                }
                assert!(seen.iter().all(|&c| c == 1), "len {len} n {n}");
            }
        }
    }

    #[test]
    fn a_table_is_its_items_bodies_under_one_header() {
        use crate::summary::SummaryRow;
        let row = |c: &str, m: &str, x: f64| SummaryRow {
            campaign: c.into(),
            method: m.into(),
            mass_kg: x,
            warnings: "a, \"quoted\"\nline".into(),
            ..Default::default()
        };
        let items = [
            vec![
                row("a", "bretl_conti", 1.5),
                row("a", "toivola_nuutila", 0.1 + 0.2),
            ],
            vec![],
            vec![row("b/c.uff", "error", f64::NAN)],
        ];
        let all: Vec<SummaryRow> = items.iter().flatten().cloned().collect();
        let records: Vec<ItemRecord> = items
            .iter()
            .enumerate()
            .map(|(i, rows)| {
                let o = ItemOutcome {
                    rows: rows.clone(),
                    warnings: vec![],
                };
                record(i, format!("{i}"), &o).unwrap()
            })
            .collect();
        assert_eq!(
            summary_text(&records).unwrap(),
            crate::summary::to_csv(&all).unwrap()
        );
        assert_eq!(summary_text(&records[1..2]).unwrap(), "");
    }
}
