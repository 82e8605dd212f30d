//! Where `frf-est` reads a time record's samples from: the parsed file itself
//! ([`InMemory`], for records built from MCAP or CSV), or an anonymous temporary file the
//! samples were set aside in as a universal file was read ([`SetAside`]). A recording of
//! tens of millions of samples is then never held whole: each hit's records are read
//! back when its checks run and again when it is averaged, so the estimate holds a hit at
//! a time per thread beside the spectral sums (issue 36: peak memory within twice the
//! recording's samples as f32).

use anyhow::{Context, Result};
use rbprops_uff::{timehist, Dataset, Record, UffError, UffFile};
use std::borrow::Cow;
use std::io::{Read, Seek, SeekFrom, Write};
use std::ops::Range;
use std::sync::Mutex;

/// A source of time records' samples, by dataset index.
pub trait SampleSource: Sync {
    /// Samples `range` (the whole record when `None`) of dataset `i`, a time record.
    fn record<'a>(
        &'a self,
        data: &'a UffFile,
        i: usize,
        range: Option<Range<usize>>,
    ) -> Result<Cow<'a, [f64]>>;
}

/// The samples are in the parsed file (`Function::samples`): borrowed, never copied.
pub struct InMemory;

impl SampleSource for InMemory {
    fn record<'a>(
        &'a self,
        data: &'a UffFile,
        i: usize,
        range: Option<Range<usize>>,
    ) -> Result<Cow<'a, [f64]>> {
        let s = timehist::samples(data, i);
        Ok(Cow::Borrowed(match range {
            Some(r) => &s[r],
            None => s,
        }))
    }
}

/// Time records' samples set aside, as little-endian f64, in an anonymous temporary file
/// (deleted when dropped): the operating system's page cache holds them, not the process.
pub struct SetAside {
    file: Mutex<std::fs::File>,
    /// Per dataset index: the byte offset of its first sample and its sample count.
    at: Vec<Option<(u64, usize)>>,
    end: u64,
    bytes: Vec<u8>,
}

impl SetAside {
    /// An empty store in the system's temporary directory.
    pub fn new() -> Result<Self> {
        let file = tempfile::tempfile().context("a temporary file for the recording's samples")?;
        Ok(SetAside {
            file: Mutex::new(file),
            at: Vec::new(),
            end: 0,
            bytes: Vec::new(),
        })
    }

    /// Moves a time record's samples out of dataset `d` (dataset index
    /// `d.location.index − 1` of its file) into the store, leaving their count in `Function::samples_set_aside`. A
    /// sample that is not a finite number is the record's error, as the index would name
    /// it.
    pub fn take(&mut self, d: &mut Dataset, file_name: &str) -> Result<(), UffError> {
        let Record::Function(f) = &mut d.record else {
            return Ok(());
        };
        if f.samples.is_empty() {
            return Ok(());
        }
        if let Some(k) = f.samples.iter().position(|v| !v.is_finite()) {
            return Err(UffError::Field {
                file: file_name.to_string(),
                at: d.location.clone(),
                field: format!("record 12 value {}", k + 1),
                problem: "not a finite number".into(),
            });
        }
        self.bytes.clear();
        self.bytes
            .extend(f.samples.iter().flat_map(|v| v.to_le_bytes()));
        let io = |e: std::io::Error| UffError::Structure {
            file: file_name.to_string(),
            line: d.location.line,
            problem: format!("cannot set the samples aside in a temporary file: {e}"),
        };
        self.file
            .get_mut()
            .expect("not poisoned")
            .write_all(&self.bytes)
            .map_err(io)?;
        let i = d.location.index - 1;
        if self.at.len() <= i {
            self.at.resize(i + 1, None);
        }
        self.at[i] = Some((self.end, f.samples.len()));
        self.end += self.bytes.len() as u64;
        f.samples_set_aside = f.samples.len();
        f.samples = Vec::new();
        Ok(())
    }
}

impl SampleSource for SetAside {
    fn record<'a>(
        &'a self,
        data: &'a UffFile,
        i: usize,
        range: Option<Range<usize>>,
    ) -> Result<Cow<'a, [f64]>> {
        let Some((start, n)) = self.at.get(i).copied().flatten() else {
            return InMemory.record(data, i, range);
        };
        let r = range.unwrap_or(0..n);
        assert!(r.end <= n, "a range within the record");
        let mut bytes = vec![0u8; 8 * r.len()];
        {
            let mut file = self.file.lock().expect("not poisoned");
            file.seek(SeekFrom::Start(start + 8 * r.start as u64))
                .and_then(|_| file.read_exact(&mut bytes))
                .with_context(|| {
                    format!(
                        "{}: dataset {}: reading back its samples from the temporary file",
                        data.file_name,
                        i + 1
                    )
                })?;
        }
        let samples = bytes
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        Ok(Cow::Owned(samples))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture() -> (String, Vec<u8>) {
        let p = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../fixtures/timehist/small-per-hit.uff"
        );
        (p.to_string(), std::fs::read(p).expect("the fixture"))
    }

    #[test]
    fn set_aside_samples_read_back_exactly_whole_and_in_stretches() {
        let (name, bytes) = fixture();
        let whole = rbprops_uff::parse(&bytes, &name).expect("parses");
        let mut store = SetAside::new().expect("a temporary file");
        let headers =
            rbprops_uff::parse_reader_each(&bytes[..], &name, |_| {}, |d| store.take(d, &name))
                .expect("parses");
        let mut records = 0;
        for (i, d) in whole.datasets.iter().enumerate() {
            let Record::Function(f) = &d.record else {
                continue;
            };
            if f.samples.is_empty() {
                continue;
            }
            records += 1;
            let Record::Function(h) = &headers.datasets[i].record else {
                panic!("dataset {i} is a function in both");
            };
            assert!(h.samples.is_empty());
            assert_eq!(h.len(), f.samples.len());
            let back = store.record(&headers, i, None).expect("read back");
            assert_eq!(back.as_ref(), &f.samples[..], "dataset {i}");
            let n = f.samples.len();
            let stretch = store
                .record(&headers, i, Some(n / 3..n / 2))
                .expect("read back");
            assert_eq!(stretch.as_ref(), &f.samples[n / 3..n / 2], "dataset {i}");
        }
        assert!(records > 10, "the fixture holds time records ({records})");
    }

    #[test]
    fn a_non_finite_sample_is_the_records_error() {
        let (name, bytes) = fixture();
        let mut whole = rbprops_uff::parse(&bytes, &name).expect("parses");
        let d = whole
            .datasets
            .iter_mut()
            .find(|d| matches!(&d.record, Record::Function(f) if !f.samples.is_empty()))
            .expect("a time record");
        let Record::Function(f) = &mut d.record else {
            unreachable!()
        };
        f.samples[5] = f64::NAN;
        let mut store = SetAside::new().expect("a temporary file");
        let e = store.take(d, &name).expect_err("NaN refused").to_string();
        assert!(
            e.contains("record 12 value 6") && e.contains("not a finite number"),
            "{e}"
        );
    }
}
