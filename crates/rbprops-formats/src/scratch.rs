//! Values kept in a scratch file by key (issue 41 and issue 36's recordings): written
//! once as raw little-endian f64, read back whole or in stretches, bit for bit. A stage
//! that passes over data again and again without holding it keeps them here: the copies
//! live in the page cache, not in the stage's memory. The caller makes the file (an
//! unnamed temporary file, `tempfile::tempfile`), so that the store does no file-system
//! policy of its own.

use std::io::{Read, Seek, SeekFrom, Write};
use std::ops::Range;

/// Raw f64 values in a scratch file, by key.
#[derive(Debug)]
pub struct ScratchValues {
    file: std::fs::File,
    /// Per key: the byte offset of its first value and its number of values.
    at: Vec<Option<(u64, usize)>>,
    end: u64,
}

impl ScratchValues {
    /// An empty store in `file` (read and write, empty).
    pub fn new(file: std::fs::File) -> Self {
        Self {
            file,
            at: Vec::new(),
            end: 0,
        }
    }

    /// The number of values kept under `key`, when there are.
    pub fn count(&self, key: usize) -> Option<usize> {
        self.at.get(key).copied().flatten().map(|(_, n)| n)
    }

    /// Writes `values` under `key` (a key written again gets the new values; the old
    /// ones stay in the file, unreferenced).
    pub fn put(&mut self, key: usize, values: impl Iterator<Item = f64>) -> std::io::Result<()> {
        let bytes: Vec<u8> = values.flat_map(f64::to_le_bytes).collect();
        self.file.seek(SeekFrom::Start(self.end))?;
        self.file.write_all(&bytes)?;
        if self.at.len() <= key {
            self.at.resize(key + 1, None);
        }
        self.at[key] = Some((self.end, bytes.len() / 8));
        self.end += bytes.len() as u64;
        Ok(())
    }

    /// Writes `values` under `key`, as [`ScratchValues::put`] does, straight from the slice.
    pub fn put_slice(&mut self, key: usize, values: &[f64]) -> std::io::Result<()> {
        if cfg!(target_endian = "big") {
            return self.put(key, values.iter().copied());
        }
        self.file.seek(SeekFrom::Start(self.end))?;
        self.file.write_all(bytemuck::cast_slice(values))?;
        if self.at.len() <= key {
            self.at.resize(key + 1, None);
        }
        self.at[key] = Some((self.end, values.len()));
        self.end += 8 * values.len() as u64;
        Ok(())
    }

    /// Reads the `out.len()` values from value `start` of those under `key` into `out`,
    /// straight from the file (no copy between); `None` when none are kept under it.
    ///
    /// # Panics
    /// When the values run past the key's.
    pub fn get_into(
        &mut self,
        key: usize,
        start: usize,
        out: &mut [f64],
    ) -> Option<std::io::Result<()>> {
        let (at, n) = self.at.get(key).copied().flatten()?;
        assert!(start + out.len() <= n, "a range within the values kept");
        let read = self
            .file
            .seek(SeekFrom::Start(at + 8 * start as u64))
            .and_then(|_| self.file.read_exact(bytemuck::cast_slice_mut(out)));
        if cfg!(target_endian = "big") {
            for x in out.iter_mut() {
                *x = f64::from_le_bytes(x.to_ne_bytes());
            }
        }
        Some(read)
    }

    /// Values `range` of those under `key` (all of them when `None`); `None` when none
    /// are kept under it.
    ///
    /// # Panics
    /// When `range` runs past the key's values.
    pub fn get(
        &mut self,
        key: usize,
        range: Option<Range<usize>>,
    ) -> Option<std::io::Result<Vec<f64>>> {
        let (start, n) = self.at.get(key).copied().flatten()?;
        let r = range.unwrap_or(0..n);
        assert!(r.end <= n, "a range within the values kept");
        let mut bytes = vec![0u8; 8 * r.len()];
        let read = self
            .file
            .seek(SeekFrom::Start(start + 8 * r.start as u64))
            .and_then(|_| self.file.read_exact(&mut bytes));
        Some(read.map(|_| {
            bytes
                .chunks_exact(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
                .collect()
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Values come back bit for bit (signed zeros, subnormals, extremes, NaN payloads),
    /// whole and in stretches, under keys written in any order; a key never written has
    /// none; a key written again gives its new values.
    #[test]
    fn values_come_back_bit_for_bit_whole_and_in_stretches() {
        let mut s = ScratchValues::new(tempfile::tempfile().unwrap());
        let odd = [
            0.0,
            -0.0,
            f64::MIN_POSITIVE / 8.0,
            f64::MAX,
            -f64::MAX,
            f64::from_bits(0x7ff8_0000_0000_0123),
        ];
        let a: Vec<f64> = (0..1000).map(|i| (i as f64 * 0.37).sin()).collect();
        s.put(7, odd.iter().copied()).unwrap();
        s.put(2, a.iter().copied()).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&s.get(7, None).unwrap().unwrap()), bits(&odd));
        assert_eq!(
            bits(&s.get(2, Some(300..450)).unwrap().unwrap()),
            bits(&a[300..450])
        );
        assert_eq!(
            (s.count(2), s.count(7), s.count(3)),
            (Some(1000), Some(6), None)
        );
        assert!(s.get(3, None).is_none() && s.get(99, None).is_none());
        s.put(7, [1.5].into_iter()).unwrap();
        assert_eq!(s.get(7, None).unwrap().unwrap(), vec![1.5]);
        // Straight from and into slices: the same values.
        s.put_slice(4, &odd).unwrap();
        let mut back = vec![9.0; 3];
        s.get_into(4, 2, &mut back).unwrap().unwrap();
        assert_eq!(bits(&back), bits(&odd[2..5]));
        s.get_into(2, 300, &mut back).unwrap().unwrap();
        assert_eq!(bits(&back), bits(&a[300..303]));
        assert!(s.get_into(5, 0, &mut back).is_none());
    }
}
