//! Where the bootstrap keeps, out of memory, what it would otherwise hold whole (issue
//! 41's bound): the model's replicates' grids and each replicate's draws, when a set is
//! larger than it holds. The crate does no I/O: the caller gives a way to make stores
//! (`rb-solve`: raw values in an unnamed temporary file, whose copies live in the page
//! cache, not in the stage's memory).

use rbprops_core::c64;
use std::sync::{Arc, Mutex};

/// Values of f64 by key: written once, read back bit for bit, whole or in stretches.
pub trait ValueStore: Send {
    /// Writes `values` under `key`.
    fn put(&mut self, key: usize, values: &[f64]) -> std::io::Result<()>;
    /// The `out.len()` values from value `start` of those under `key`, into `out`.
    fn get_into(&mut self, key: usize, start: usize, out: &mut [f64]) -> std::io::Result<()>;
}

/// A maker of [`ValueStore`]s and the largest data the bootstrap holds in memory.
#[derive(Clone)]
pub struct Scratch {
    make: Arc<dyn Fn() -> std::io::Result<Box<dyn ValueStore>> + Send + Sync>,
    held_bytes: usize,
}

impl std::fmt::Debug for Scratch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Scratch {{ held_bytes: {} }}", self.held_bytes)
    }
}

/// Two scratch options are the same when they make stores the same way.
impl PartialEq for Scratch {
    fn eq(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.make, &other.make) && self.held_bytes == other.held_bytes
    }
}

impl Scratch {
    /// The most bytes of FRF values held whole by default (4 MB: 290 excitations of 9
    /// channels × 100 lines, or one of 9 channels × 29,000 lines): a set-up within it
    /// costs no store reads.
    pub const HELD_BYTES: usize = 4 << 20;

    /// Stores made by `make`; data of more than `held_bytes` bytes go to them.
    pub fn new(
        make: impl Fn() -> std::io::Result<Box<dyn ValueStore>> + Send + Sync + 'static,
        held_bytes: usize,
    ) -> Self {
        Self {
            make: Arc::new(make),
            held_bytes,
        }
    }

    /// A store for data of `bytes` bytes, or `None` when they are held: within the
    /// limit, or when no store can be made (no writable temporary directory: the same
    /// values held, as the modal fit decodes an excitation again rather than fail).
    pub(crate) fn store_for(scratch: Option<&Self>, bytes: usize) -> Option<SharedStore> {
        match scratch {
            Some(s) if bytes > s.held_bytes => {
                (s.make)().ok().map(|store| SharedStore(Mutex::new(store)))
            }
            _ => None,
        }
    }
}

/// A store read from several threads.
pub(crate) struct SharedStore(Mutex<Box<dyn ValueStore>>);

impl std::fmt::Debug for SharedStore {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("SharedStore")
    }
}

impl SharedStore {
    fn lock(&self) -> std::sync::MutexGuard<'_, Box<dyn ValueStore>> {
        // A panic elsewhere while holding the lock leaves the store as it was.
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Writes complex `channels` under `key`, each as its re, im pairs, then `extra`.
    pub(crate) fn put_channels(
        &self,
        key: usize,
        channels: &[Vec<c64>],
        extra: &[f64],
    ) -> std::io::Result<()> {
        let mut v: Vec<f64> = channels
            .iter()
            .flatten()
            .flat_map(|z| [z.re, z.im])
            .collect();
        v.extend_from_slice(extra);
        self.lock().put(key, &v)
    }

    /// Channel `c` of those of `n` lines under `key` ([`SharedStore::put_channels`]),
    /// read straight into its values (a replicate's set-up is read once per trial).
    pub(crate) fn channel(&self, key: usize, c: usize, n: usize) -> std::io::Result<Vec<c64>> {
        let mut h = vec![c64::new(0.0, 0.0); n];
        self.lock()
            .get_into(key, 2 * n * c, bytemuck::cast_slice_mut(&mut h))?;
        Ok(h)
    }

    /// All `n_channels` channels of `n` lines under `key`, and the `extra` values after them.
    pub(crate) fn channels(
        &self,
        key: usize,
        n_channels: usize,
        n: usize,
        extra: usize,
    ) -> std::io::Result<(Vec<Vec<c64>>, Vec<f64>)> {
        let channels = (0..n_channels)
            .map(|c| self.channel(key, c, n))
            .collect::<std::io::Result<_>>()?;
        let mut rest = vec![0.0; extra];
        self.lock().get_into(key, 2 * n * n_channels, &mut rest)?;
        Ok((channels, rest))
    }
}

/// A store in memory (for tests: the stored path without a file).
#[derive(Debug, Default)]
pub struct MemoryStore(Vec<Vec<f64>>);

impl ValueStore for MemoryStore {
    fn put(&mut self, key: usize, values: &[f64]) -> std::io::Result<()> {
        if self.0.len() <= key {
            self.0.resize(key + 1, Vec::new());
        }
        self.0[key] = values.to_vec();
        Ok(())
    }
    fn get_into(&mut self, key: usize, start: usize, out: &mut [f64]) -> std::io::Result<()> {
        let values = self
            .0
            .get(key)
            .and_then(|v| v.get(start..start + out.len()))
            .ok_or_else(|| std::io::Error::other(format!("no values {start}.. under key {key}")))?;
        out.copy_from_slice(values);
        Ok(())
    }
}
