//! Content digests for the formats that cannot carry CRCs: CSV directories and UFF files.
//!
//! MCAP checks itself (chunk and data-section CRCs, see [`crate::mcap_file`]). A CSV
//! directory or a UFF file is text a person may open and save, so it carries instead the
//! SHA-256 of its content, recorded when it is written and checked when a stage reads it:
//! - **CSV directory**: the last provenance row's `content_sha256` covers every file the
//!   reader uses except the provenance tables themselves (the manifest, each other table,
//!   each other topic's schema, `frf_info.csv`, `frf.csv`), hashed in that order, each as
//!   its relative path, a NUL, its length (u64 little-endian) and its bytes.
//! - **UFF**: a leading dataset 151 (header) whose description line is `sha256 <hex>` of
//!   all the bytes after that dataset.
//!
//! A directory or file without such a claim (another program's) is read unchecked; the
//! stages say so under `-v`.

use crate::{csv_dir, topics, FormatError};
use sha2::Digest;
use std::path::Path;

/// Field of the provenance message that carries a CSV directory's content digest.
pub const CONTENT_FIELD: &str = "content_sha256";

/// The outcome of checking a content digest.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DigestCheck {
    /// The content matches the digest `tool` recorded.
    Matches {
        /// Who recorded the digest (the stage's tool name).
        tool: String,
    },
    /// No digest is recorded: nothing to check against.
    Unclaimed,
    /// The content changed after `tool` recorded its digest.
    Mismatch {
        /// Who recorded the digest (the stage's tool name).
        tool: String,
        /// The digest recorded in the provenance, hex SHA-256.
        recorded: String,
        /// The digest of the content as it is now, hex SHA-256.
        found: String,
    },
}

impl DigestCheck {
    /// The verdict of comparing the digest `tool` recorded with the one `found` now.
    fn compare(tool: String, recorded: String, found: String) -> Self {
        if found == recorded {
            DigestCheck::Matches { tool }
        } else {
            DigestCheck::Mismatch {
                tool,
                recorded,
                found,
            }
        }
    }
}

fn hex(d: &[u8]) -> String {
    d.iter().map(|b| format!("{b:02x}")).collect()
}

/// SHA-256 of a CSV directory's content files (see the module docs), with the names of
/// the provenance tables it leaves out.
pub fn csv_content_sha256(dir: &Path) -> Result<String, FormatError> {
    let entries = csv_dir::read_manifest(dir)?;
    let mut files = vec![csv_dir::MANIFEST.to_string()];
    for [table, topic, parent, _, _, _, _] in &entries {
        if topic == topics::PROVENANCE {
            continue;
        }
        files.push(format!("{table}.csv"));
        if parent.is_empty() && dir.join("schemas").join(format!("{table}.json")).exists() {
            files.push(format!("schemas/{table}.json"));
        }
    }
    for f in ["frf_info.csv", "frf.csv"] {
        if dir.join(f).exists() {
            files.push(f.into());
        }
    }
    let mut h = sha2::Sha256::new();
    for f in &files {
        let p = dir.join(f);
        let bytes = std::fs::read(&p).map_err(|e| FormatError::Io {
            file: p.display().to_string(),
            source: e,
        })?;
        h.update(f.as_bytes());
        h.update([0u8]);
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(&bytes);
    }
    Ok(hex(&h.finalize()))
}

/// Checks a CSV directory against the digest its last provenance row records.
pub fn check_csv(dir: &Path) -> Result<DigestCheck, FormatError> {
    let name = dir.display().to_string();
    let prov = csv_dir::read_topic_messages(dir, topics::PROVENANCE)?;
    let Some(last) = prov.last() else {
        return Ok(DigestCheck::Unclaimed);
    };
    let tool = last
        .get("tool")
        .and_then(|t| t.as_str())
        .unwrap_or("?")
        .to_string();
    let recorded = match last.get(CONTENT_FIELD) {
        None | Some(serde_json::Value::Null) => return Ok(DigestCheck::Unclaimed),
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(v) => {
            return Err(FormatError::record(
                &name,
                "provenance.csv, last row",
                format!("{CONTENT_FIELD} {v} is not a hex digest"),
            ))
        }
    };
    let found = csv_content_sha256(dir)?;
    Ok(DigestCheck::compare(tool, recorded, found))
}

const UFF_DELIM: &str = "    -1\n";
const UFF_HEADER_START: &str = "    -1\n   151\n";
const UFF_DIGEST_PREFIX: &str = "sha256 ";

/// Prefixes UFF bytes with the dataset 151 header that records their digest. The other
/// header fields are fixed (no dates), so the same content gives the same file.
pub fn uff_stamp(body: &[u8]) -> Vec<u8> {
    let digest = hex(&sha2::Sha256::digest(body));
    let mut s = String::from(UFF_HEADER_START);
    // Dataset 151 records 1–7: model name, description, creating program, created
    // (date, time, versions, file type), saved (date, time), writing program, written.
    s.push_str(&format!("{:<80}\n", "rbprops run"));
    s.push_str(&format!("{:<80}\n", format!("{UFF_DIGEST_PREFIX}{digest}")));
    s.push_str(&format!(
        "{:<80}\n",
        format!("rbprops {}", env!("CARGO_PKG_VERSION"))
    ));
    s.push_str(&format!(
        "{:<10}{:<10}{:>10}{:>10}{:>10}\n",
        "", "", 0, 0, 0
    ));
    s.push_str(&format!("{:<10}{:<10}\n", "", ""));
    s.push_str(&format!("{:<80}\n", "rbprops"));
    s.push_str(&format!("{:<10}{:<10}\n", "", ""));
    s.push_str(UFF_DELIM);
    let mut out = s.into_bytes();
    out.extend_from_slice(body);
    out
}

/// Checks a UFF file that starts with the header of [`uff_stamp`]; other files are
/// [`DigestCheck::Unclaimed`].
pub fn check_uff(bytes: &[u8]) -> DigestCheck {
    let Some(rest) = bytes.strip_prefix(UFF_HEADER_START.as_bytes()) else {
        return DigestCheck::Unclaimed;
    };
    let mut lines = rest.split_inclusive(|&b| b == b'\n');
    let (Some(_model), Some(desc)) = (lines.next(), lines.next()) else {
        return DigestCheck::Unclaimed;
    };
    let Some(recorded) = desc.strip_prefix(UFF_DIGEST_PREFIX.as_bytes()) else {
        return DigestCheck::Unclaimed;
    };
    let recorded = String::from_utf8_lossy(recorded).trim().to_string();
    // The header ends at its closing delimiter; the digest covers everything after it.
    let mut at = UFF_HEADER_START.len();
    let mut body_start = None;
    for line in rest.split_inclusive(|&b| b == b'\n') {
        at += line.len();
        if line == UFF_DELIM.as_bytes() {
            body_start = Some(at);
            break;
        }
    }
    let Some(start) = body_start else {
        return DigestCheck::Unclaimed;
    };
    let found = hex(&sha2::Sha256::digest(&bytes[start..]));
    DigestCheck::compare("rbprops (UFF header)".to_string(), recorded, found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uff_stamp_round_trip_and_every_body_byte_counts() {
        let body = b"    -1\n    58\nsome data 1.0E+00\n    -1\n";
        let stamped = uff_stamp(body);
        assert_eq!(
            check_uff(&stamped),
            DigestCheck::Matches {
                tool: "rbprops (UFF header)".into()
            }
        );
        assert!(stamped.ends_with(body));
        let start = stamped.len() - body.len();
        for i in start..stamped.len() {
            let mut m = stamped.clone();
            m[i] ^= 0x01;
            assert!(
                matches!(check_uff(&m), DigestCheck::Mismatch { .. }),
                "flip at byte {i} not caught"
            );
        }
        assert_eq!(check_uff(body), DigestCheck::Unclaimed);
    }
}
