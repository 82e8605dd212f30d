//! Running spectral sums over accepted hits.
//!
//! For hit `d` with (windowed) force records `f_r` (r = 1..n_refs) and response records
//! `x_o` (o = 1..n_resp) of N samples, `F_r,k` and `X_o,k` are their one-sided DFTs
//! (`k = 0..=N/2`, `X_k = Σ_n x[n] e^{−2πikn/N}`, unscaled) and
//!
//! ```text
//!   S_ff[k]_{rs} = Σ_d F_r F̄_s     S_xf[k]_{or} = Σ_d X_o F̄_r     S_xx[k]_o = Σ_d |X_o|²
//! ```
//!
//! Hits are added one at a time ([`SpectralSums::add_hit`]), so estimates can be taken
//! after every hit. One real-FFT plan per record length, built once; the scratch buffers
//! live in the struct, so adding a hit does not allocate. The sums are accumulated in the
//! order the hits are added, channel by channel: the same hits in the same order give
//! bit-identical sums.

use crate::{c64, FrfError};
use realfft::{RealFftPlanner, RealToComplex};
use std::sync::Arc;

/// The running sums of one excitation (module docs).
#[derive(Clone)]
pub struct SpectralSums {
    n: usize,
    fs: f64,
    n_refs: usize,
    n_resp: usize,
    lines: usize,
    count: usize,
    /// `[k][r][s]`.
    sff: Vec<c64>,
    /// `[o][k][r]`.
    sxf: Vec<c64>,
    /// `[o][k]`.
    sxx: Vec<f64>,
    fft: Arc<dyn RealToComplex<f64>>,
    input: Vec<f64>,
    scratch: Vec<c64>,
    /// The current hit's force spectra `[r][k]`.
    spec_f: Vec<c64>,
    /// The current response spectrum `[k]`.
    spec_x: Vec<c64>,
}

impl std::fmt::Debug for SpectralSums {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SpectralSums")
            .field("n", &self.n)
            .field("fs", &self.fs)
            .field("n_refs", &self.n_refs)
            .field("n_resp", &self.n_resp)
            .field("count", &self.count)
            .finish()
    }
}

impl SpectralSums {
    /// Empty sums for records of `record_len` samples at `fs`, `n_refs` force and `n_resp`
    /// response channels. Plans the real FFT once.
    pub fn new(record_len: usize, fs: f64, n_refs: usize, n_resp: usize) -> Result<Self, FrfError> {
        crate::hit::check_record(record_len, fs)?;
        if n_refs == 0 || n_resp == 0 {
            return Err(FrfError::Invalid(format!(
                "{n_refs} references and {n_resp} responses: at least one of each needed"
            )));
        }
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(record_len);
        let lines = record_len / 2 + 1;
        let scratch = fft.make_scratch_vec();
        Ok(SpectralSums {
            n: record_len,
            fs,
            n_refs,
            n_resp,
            lines,
            count: 0,
            sff: vec![c64::new(0.0, 0.0); lines * n_refs * n_refs],
            sxf: vec![c64::new(0.0, 0.0); n_resp * lines * n_refs],
            sxx: vec![0.0; n_resp * lines],
            fft,
            input: vec![0.0; record_len],
            scratch,
            spec_f: vec![c64::new(0.0, 0.0); n_refs * lines],
            spec_x: vec![c64::new(0.0, 0.0); lines],
        })
    }

    /// Adds one hit whose records are already windowed.
    pub fn add_hit(&mut self, forces: &[&[f64]], responses: &[&[f64]]) -> Result<(), FrfError> {
        self.add_windowed_hit(forces, responses, None, None)
    }

    /// Adds one hit, multiplying the forces by `force_window` and the responses by
    /// `response_window` on the way (None: as given). No allocation.
    pub fn add_windowed_hit(
        &mut self,
        forces: &[&[f64]],
        responses: &[&[f64]],
        force_window: Option<&[f64]>,
        response_window: Option<&[f64]>,
    ) -> Result<(), FrfError> {
        self.check(forces, responses, force_window, response_window)?;
        let (n, lines, nr) = (self.n, self.lines, self.n_refs);
        for (r, f) in forces.iter().enumerate() {
            load(&mut self.input, f, force_window);
            self.fft
                .process_with_scratch(
                    &mut self.input,
                    &mut self.spec_f[r * lines..(r + 1) * lines],
                    &mut self.scratch,
                )
                .expect("lengths checked");
        }
        debug_assert_eq!(self.input.len(), n);
        for k in 0..lines {
            let base = k * nr * nr;
            for r in 0..nr {
                let fr = self.spec_f[r * lines + k];
                for s in 0..nr {
                    self.sff[base + r * nr + s] += fr * self.spec_f[s * lines + k].conj();
                }
            }
        }
        for (o, x) in responses.iter().enumerate() {
            load(&mut self.input, x, response_window);
            self.fft
                .process_with_scratch(&mut self.input, &mut self.spec_x, &mut self.scratch)
                .expect("lengths checked");
            let sxf = &mut self.sxf[o * lines * nr..(o + 1) * lines * nr];
            let sxx = &mut self.sxx[o * lines..(o + 1) * lines];
            for k in 0..lines {
                let xk = self.spec_x[k];
                sxx[k] += xk.norm_sqr();
                for r in 0..nr {
                    sxf[k * nr + r] += xk * self.spec_f[r * lines + k].conj();
                }
            }
        }
        self.count += 1;
        Ok(())
    }

    fn check(
        &self,
        forces: &[&[f64]],
        responses: &[&[f64]],
        fw: Option<&[f64]>,
        rw: Option<&[f64]>,
    ) -> Result<(), FrfError> {
        if forces.len() != self.n_refs {
            return Err(FrfError::Channels {
                what: "forces",
                got: forces.len(),
                expected: self.n_refs,
            });
        }
        if responses.len() != self.n_resp {
            return Err(FrfError::Channels {
                what: "responses",
                got: responses.len(),
                expected: self.n_resp,
            });
        }
        let named = forces
            .iter()
            .enumerate()
            .map(|(i, f)| (format!("force {i}"), f.len()))
            .chain(
                responses
                    .iter()
                    .enumerate()
                    .map(|(i, x)| (format!("response {i}"), x.len())),
            )
            .chain(fw.map(|w| ("force window".to_string(), w.len())))
            .chain(rw.map(|w| ("response window".to_string(), w.len())));
        for (what, got) in named {
            if got != self.n {
                return Err(FrfError::Length {
                    what,
                    got,
                    expected: self.n,
                });
            }
        }
        Ok(())
    }

    /// Clears the sums (the plan is kept).
    pub fn reset(&mut self) {
        self.count = 0;
        self.sff.fill(c64::new(0.0, 0.0));
        self.sxf.fill(c64::new(0.0, 0.0));
        self.sxx.fill(0.0);
    }

    /// The number of hits averaged, `n_d`.
    pub fn count(&self) -> usize {
        self.count
    }
    /// Record length N (samples).
    pub fn record_len(&self) -> usize {
        self.n
    }
    /// Sampling rate (Hz).
    pub fn fs(&self) -> f64 {
        self.fs
    }
    /// Force channels.
    pub fn n_refs(&self) -> usize {
        self.n_refs
    }
    /// Response channels.
    pub fn n_resp(&self) -> usize {
        self.n_resp
    }
    /// One-sided lines `N/2 + 1`.
    pub fn lines(&self) -> usize {
        self.lines
    }
    /// Line spacing `f_s/N` (Hz).
    pub fn line_spacing_hz(&self) -> f64 {
        self.fs / self.n as f64
    }
    /// Frequency of line k, `k f_s/N` (Hz).
    pub fn freq_hz(&self, k: usize) -> f64 {
        k as f64 * self.fs / self.n as f64
    }
    /// `S_ff[k]_{rs}`.
    pub fn sff(&self, k: usize, r: usize, s: usize) -> c64 {
        self.sff[k * self.n_refs * self.n_refs + r * self.n_refs + s]
    }
    /// `S_xf[k]_{or}`.
    pub fn sxf(&self, k: usize, o: usize, r: usize) -> c64 {
        self.sxf[(o * self.lines + k) * self.n_refs + r]
    }
    /// `S_xx[k]_o`.
    pub fn sxx(&self, k: usize, o: usize) -> f64 {
        self.sxx[o * self.lines + k]
    }
    /// The `n_refs × n_refs` block of line k, row-major.
    pub(crate) fn sff_block(&self, k: usize) -> &[c64] {
        let b = self.n_refs * self.n_refs;
        &self.sff[k * b..(k + 1) * b]
    }
    /// `S_xf[k]_{o·}`.
    pub(crate) fn sxf_row(&self, k: usize, o: usize) -> &[c64] {
        let i = (o * self.lines + k) * self.n_refs;
        &self.sxf[i..i + self.n_refs]
    }
}

/// Copies `x` (times `w`) into `buf`.
fn load(buf: &mut [f64], x: &[f64], w: Option<&[f64]>) {
    match w {
        Some(w) => {
            for ((b, x), w) in buf.iter_mut().zip(x).zip(w) {
                *b = x * w;
            }
        }
        None => buf.copy_from_slice(x),
    }
}
