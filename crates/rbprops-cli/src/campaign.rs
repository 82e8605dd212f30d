//! Batch runs: every campaign spec or recording under a directory, in parallel, one
//! summary table. Each item goes through the same stage functions as the executables
//! with their default options, so a row equals the single run's row exactly.

use crate::summary::{self, SummaryRow};
use anyhow::{Context, Result};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Something the campaign runner can process.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub enum Item {
    /// A campaign spec (TOML): simulated first.
    Spec(PathBuf),
    /// A recording (MCAP file or CSV directory) holding geometry and FRFs.
    Recording(PathBuf),
}

impl Item {
    pub fn path(&self) -> &Path {
        match self {
            Item::Spec(p) | Item::Recording(p) => p,
        }
    }
}

/// Finds specs (`*.toml`) and recordings (`*.mcap`, CSV run directories) under `dir`,
/// sorted by path so the summary order does not depend on the file system.
pub fn discover(dir: &Path) -> Result<Vec<Item>> {
    let mut out = Vec::new();
    walk(dir, &mut out).with_context(|| dir.display().to_string())?;
    out.sort();
    Ok(out)
}

fn walk(dir: &Path, out: &mut Vec<Item>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let p = e?.path();
        if p.is_dir() {
            if p.join("manifest.csv").exists() {
                out.push(Item::Recording(p));
            } else {
                walk(&p, out)?;
            }
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

/// Runs one item through the pipeline with default options (and the given uncertainty
/// method, the executables' default being the bootstrap with 100 replicates, seed 0).
pub fn run_item(
    item: &Item,
    campaign: &str,
    uncertainty: &crate::stages::Uncertainty,
) -> Result<Vec<SummaryRow>> {
    let (mut rec, sha) = match item {
        Item::Spec(p) => {
            let text = std::fs::read_to_string(p).with_context(|| p.display().to_string())?;
            let (rec, _) = crate::stages::simulate(&text, &p.display().to_string(), None)?;
            let sha = rbprops_formats::sha256_hex(&rbprops_formats::mcap_file::write(&rec)?);
            (rec, sha)
        }
        Item::Recording(p) => {
            let inp = crate::read_input(Some(p))?;
            (inp.record, inp.sha256)
        }
    };
    let name = item.path().display().to_string();
    crate::stages::modal_fit(&mut rec, &Default::default(), &sha).with_context(|| name.clone())?;
    crate::stages::ni_select(&mut rec, &Default::default(), &sha).with_context(|| name.clone())?;
    crate::stages::rb_solve_with(&mut rec, &Default::default(), uncertainty, true, &sha)
        .with_context(|| name.clone())?;
    summary::rows(&rec, campaign, "ni", "geometry")
}

/// Runs every item in parallel. Failed items become one row with method `error` and the
/// message in `warnings`, so the table still accounts for every input.
pub fn run_all(
    items: &[Item],
    root: &Path,
    uncertainty: &crate::stages::Uncertainty,
    progress: &indicatif::ProgressBar,
) -> (Vec<SummaryRow>, usize) {
    let results: Vec<Vec<SummaryRow>> = items
        .par_iter()
        .map(|item| {
            let campaign = item
                .path()
                .strip_prefix(root)
                .unwrap_or(item.path())
                .display()
                .to_string();
            let rows = run_item(item, &campaign, uncertainty).unwrap_or_else(|e| {
                vec![SummaryRow {
                    campaign: campaign.clone(),
                    set: "ni".into(),
                    origin: "geometry".into(),
                    method: "error".into(),
                    warnings: format!("{e:#}"),
                    ..Default::default()
                }]
            });
            progress.inc(1);
            rows
        })
        .collect();
    let failed = results
        .iter()
        .filter(|r| r.len() == 1 && r[0].method == "error")
        .count();
    (results.into_iter().flatten().collect(), failed)
}
