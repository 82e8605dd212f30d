//! Manual mode sets ("mode 1 from force 2, …", the paper's Sets I–V) and their parsers.
//!
//! Three text forms are accepted (the library does no I/O: the caller reads the file):
//! - compact: `1:F2,2:F2,3:F3,4:F3,5:F1,6:F1` (`mode:excitation`, commas or whitespace
//!   between entries; see [`parse_manual_set`]);
//! - TOML ([`ManualSet::from_toml`]): a `[modes]` table `1 = "F2"`, or `[[mode]]` entries
//!   with `mode = 1` and `excitation = "F2"`;
//! - CSV ([`ManualSet::from_csv`]): a `mode,excitation` header and one entry per line.
//!
//! Mode numbers are the physical (matched) mode numbers within the set-up, 1-based;
//! excitation ids are the geometry's.

use crate::NiError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// One manual choice: physical mode `mode` is taken from excitation `excitation`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ManualEntry {
    /// 1-based physical mode number within the set-up.
    pub mode: usize,
    /// Id of the excitation whose estimate is taken.
    pub excitation: String,
}

/// A manual set, sorted by mode; each mode appears once.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize, schemars::JsonSchema)]
pub struct ManualSet {
    /// One entry per mode, by ascending mode.
    pub entries: Vec<ManualEntry>,
}

impl ManualSet {
    /// Builds a set from entries, refusing mode 0, empty ids and repeated modes.
    pub fn new(entries: Vec<ManualEntry>) -> Result<Self, NiError> {
        let mut by_mode: BTreeMap<usize, String> = BTreeMap::new();
        for e in entries {
            if e.mode == 0 {
                return Err(NiError::ManualParse {
                    item: format!("0:{}", e.excitation),
                    message: "mode numbers start at 1".into(),
                });
            }
            if e.excitation.trim().is_empty() {
                return Err(NiError::ManualParse {
                    item: format!("mode {}", e.mode),
                    message: "empty excitation id".into(),
                });
            }
            if let Some(prev) = by_mode.get(&e.mode) {
                return Err(NiError::ManualParse {
                    item: format!("{}:{}", e.mode, e.excitation),
                    message: format!("mode {} is already taken from '{prev}'", e.mode),
                });
            }
            by_mode.insert(e.mode, e.excitation.trim().to_string());
        }
        if by_mode.is_empty() {
            return Err(NiError::ManualParse {
                item: "(whole set)".into(),
                message: "no entries".into(),
            });
        }
        Ok(Self {
            entries: by_mode
                .into_iter()
                .map(|(mode, excitation)| ManualEntry { mode, excitation })
                .collect(),
        })
    }

    /// The excitation chosen for `mode`, if any.
    pub fn excitation_for(&self, mode: usize) -> Option<&str> {
        self.entries
            .iter()
            .find(|e| e.mode == mode)
            .map(|e| e.excitation.as_str())
    }

    /// The compact form `1:F2,2:F2,…`.
    pub fn to_compact(&self) -> String {
        self.entries
            .iter()
            .map(|e| format!("{}:{}", e.mode, e.excitation))
            .collect::<Vec<_>>()
            .join(",")
    }

    /// Parses the TOML form: either a `[modes]` table (`1 = "F2"`) or an array of
    /// tables `[[mode]]` with `mode` and `excitation` keys.
    pub fn from_toml(text: &str) -> Result<Self, NiError> {
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct File {
            modes: Option<BTreeMap<String, String>>,
            mode: Option<Vec<ManualEntry>>,
        }
        let file: File = toml::from_str(text).map_err(|e| NiError::ManualParse {
            item: "TOML".into(),
            message: e.to_string().trim().to_string(),
        })?;
        let mut entries = Vec::new();
        if let Some(map) = file.modes {
            for (k, v) in map {
                entries.push(ManualEntry {
                    mode: parse_mode(&k, &format!("[modes] key '{k}'"))?,
                    excitation: v,
                });
            }
        }
        entries.extend(file.mode.unwrap_or_default());
        if entries.is_empty() {
            return Err(NiError::ManualParse {
                item: "TOML".into(),
                message: "expected a [modes] table (1 = \"F2\") or [[mode]] entries".into(),
            });
        }
        Self::new(entries)
    }

    /// Parses the CSV form: header `mode,excitation` (case-insensitive, any order of the
    /// two columns), then one entry per line; blank lines and `#` comments are skipped.
    pub fn from_csv(text: &str) -> Result<Self, NiError> {
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let (hn, header) = lines.next().ok_or_else(|| NiError::ManualParse {
            item: "CSV".into(),
            message: "empty file".into(),
        })?;
        let cols: Vec<String> = header
            .split(',')
            .map(|c| c.trim().trim_matches('"').to_ascii_lowercase())
            .collect();
        let find = |name: &str| cols.iter().position(|c| c == name);
        let (Some(im), Some(ie)) = (find("mode"), find("excitation")) else {
            return Err(NiError::ManualParse {
                item: format!("CSV line {hn}"),
                message: format!(
                    "header must name columns 'mode' and 'excitation', found '{header}'"
                ),
            });
        };
        let mut entries = Vec::new();
        for (n, line) in lines {
            let f: Vec<&str> = line
                .split(',')
                .map(|c| c.trim().trim_matches('"'))
                .collect();
            if f.len() != cols.len() {
                return Err(NiError::ManualParse {
                    item: format!("CSV line {n}"),
                    message: format!("{} fields, header has {}", f.len(), cols.len()),
                });
            }
            entries.push(ManualEntry {
                mode: parse_mode(f[im], &format!("CSV line {n}"))?,
                excitation: f[ie].to_string(),
            });
        }
        Self::new(entries)
    }
}

fn parse_mode(s: &str, item: &str) -> Result<usize, NiError> {
    s.trim().parse::<usize>().map_err(|_| NiError::ManualParse {
        item: item.into(),
        message: format!("mode number '{}' is not a positive integer", s.trim()),
    })
}

/// Parses the compact form `1:F2,2:F2,3:F3,4:F3,5:F1,6:F1`: entries `mode:excitation`
/// separated by commas, semicolons or whitespace. Errors name the offending entry.
pub fn parse_manual_set(text: &str) -> Result<ManualSet, NiError> {
    let mut entries = Vec::new();
    for item in text
        .split(|c: char| c == ',' || c == ';' || c.is_whitespace())
        .filter(|s| !s.is_empty())
    {
        let Some((m, e)) = item.split_once(':') else {
            return Err(NiError::ManualParse {
                item: format!("'{item}'"),
                message: "expected mode:excitation, e.g. 1:F2".into(),
            });
        };
        if e.trim().is_empty() || e.contains(':') {
            return Err(NiError::ManualParse {
                item: format!("'{item}'"),
                message: "expected one excitation id after ':'".into(),
            });
        }
        entries.push(ManualEntry {
            mode: parse_mode(m, &format!("'{item}'"))?,
            excitation: e.trim().to_string(),
        });
    }
    ManualSet::new(entries)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn compact_form_parses_the_papers_set_one() {
        let s = parse_manual_set("1:F2,2:F2,3:F3,4:F3,5:F1,6:F1").unwrap();
        assert_eq!(s.entries.len(), 6);
        assert_eq!(s.excitation_for(3), Some("F3"));
        assert_eq!(s.excitation_for(5), Some("F1"));
        assert_eq!(s.to_compact(), "1:F2,2:F2,3:F3,4:F3,5:F1,6:F1");
        // Order and separators do not matter.
        let t = parse_manual_set(" 6:F1; 5:F1 4:F3,3:F3\n2:F2 1:F2 ").unwrap();
        assert_eq!(s, t);
    }

    #[test]
    fn compact_form_errors_name_the_entry() {
        let e = parse_manual_set("1:F2,2F2").unwrap_err().to_string();
        assert!(e.contains("'2F2'") && e.contains("mode:excitation"), "{e}");
        let e = parse_manual_set("1:F2,x:F3").unwrap_err().to_string();
        assert!(
            e.contains("'x:F3'") && e.contains("not a positive integer"),
            "{e}"
        );
        let e = parse_manual_set("1:F2,1:F3").unwrap_err().to_string();
        assert!(e.contains("already taken from 'F2'"), "{e}");
        let e = parse_manual_set("0:F2").unwrap_err().to_string();
        assert!(e.contains("start at 1"), "{e}");
        assert!(parse_manual_set("  ").is_err());
        assert!(parse_manual_set("1:").is_err());
    }

    #[test]
    fn toml_forms() {
        let a = ManualSet::from_toml("[modes]\n1 = \"F2\"\n2 = \"F2\"\n3 = \"F3\"\n").unwrap();
        let b = ManualSet::from_toml(
            "[[mode]]\nmode = 3\nexcitation = \"F3\"\n[[mode]]\nmode = 1\nexcitation = \"F2\"\n\
             [[mode]]\nmode = 2\nexcitation = \"F2\"\n",
        )
        .unwrap();
        assert_eq!(a, b);
        let e = ManualSet::from_toml("[modes]\nfirst = \"F2\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("[modes] key 'first'"), "{e}");
        let e = ManualSet::from_toml("[modez]\n1 = \"F2\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("TOML"), "{e}");
    }

    #[test]
    fn csv_form() {
        let s =
            ManualSet::from_csv("# set III\nexcitation,mode\nF1,1\nF2,2\n\n\"F3\",3\n").unwrap();
        assert_eq!(s.to_compact(), "1:F1,2:F2,3:F3");
        let e = ManualSet::from_csv("mode;excitation\n1;F1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("CSV line 1"), "{e}");
        let e = ManualSet::from_csv("mode,excitation\n1,F1\n2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("CSV line 3"), "{e}");
    }
}
