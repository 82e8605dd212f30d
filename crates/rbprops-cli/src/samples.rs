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
    /// Dataset index `i`'s samples under key `i`.
    values: Mutex<rbprops_formats::scratch::ScratchValues>,
}

impl SetAside {
    /// An empty store in the system's temporary directory.
    pub fn new() -> Result<Self> {
        let file = tempfile::tempfile().context("a temporary file for the recording's samples")?;
        Ok(SetAside {
            values: Mutex::new(rbprops_formats::scratch::ScratchValues::new(file)),
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
        let io = |e: std::io::Error| UffError::Structure {
            file: file_name.to_string(),
            line: d.location.line,
            problem: format!("cannot set the samples aside in a temporary file: {e}"),
        };
        self.values
            .get_mut()
            .expect("not poisoned")
            .put(d.location.index - 1, f.samples.iter().copied())
            .map_err(io)?;
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
        let kept = self
            .values
            .lock()
            .expect("not poisoned")
            .get(i, range.clone());
        match kept {
            None => InMemory.record(data, i, range),
            Some(read) => Ok(Cow::Owned(read.with_context(|| {
                format!(
                    "{}: dataset {}: reading back its samples from the temporary file",
                    data.file_name,
                    i + 1
                )
            })?)),
        }
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

/// The bootstrap's scratch stores (issue 41's memory bound): raw values in unnamed
/// temporary files, for a model or a replicate's set-up larger than
/// [`rbprops_uq::Scratch::HELD_BYTES`].
pub fn bootstrap_scratch() -> rbprops_uq::Scratch {
    rbprops_uq::Scratch::new(
        || {
            let values = rbprops_formats::scratch::ScratchValues::new(tempfile::tempfile()?);
            Ok(Box::new(BootstrapStore(values)) as Box<dyn rbprops_uq::ValueStore>)
        },
        rbprops_uq::Scratch::HELD_BYTES,
    )
}

/// A [`rbprops_uq::ValueStore`] in a scratch file.
struct BootstrapStore(rbprops_formats::scratch::ScratchValues);

impl rbprops_uq::ValueStore for BootstrapStore {
    fn put(&mut self, key: usize, values: &[f64]) -> std::io::Result<()> {
        self.0.put_slice(key, values)
    }
    fn get_into(&mut self, key: usize, start: usize, out: &mut [f64]) -> std::io::Result<()> {
        if self.0.count(key).is_none_or(|n| start + out.len() > n) {
            return Err(std::io::Error::other(format!(
                "values {start}..{} under key {key} were not kept",
                start + out.len()
            )));
        }
        self.0
            .get_into(key, start, out)
            .expect("kept, as checked above")
    }
}
