//! FRF sets: complex frequency responses per excitation × channel × spectral line.

use crate::{c64, CoreError};
use serde::{Deserialize, Serialize};

/// What an FRF measures per newton of force.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum Quantity {
    /// Displacement / force, m/N.
    Receptance,
    /// Velocity / force, m/(N s) = iω·receptance.
    Mobility,
    /// Acceleration / force, m/(N s²) = −ω²·receptance.
    Accelerance,
}

impl Quantity {
    /// The accepted names, for error messages and help texts.
    pub const NAMES: &'static str = "receptance, mobility, accelerance";

    /// The lowercase name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Receptance => "receptance",
            Quantity::Mobility => "mobility",
            Quantity::Accelerance => "accelerance",
        }
    }

    /// SI unit of the FRF values.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Receptance => "m/N",
            Quantity::Mobility => "m/(N s)",
            Quantity::Accelerance => "m/(N s^2)",
        }
    }

    /// The factor `(iω)^k` that turns a receptance into this quantity at ω (rad/s).
    pub fn from_receptance_factor(self, omega: f64) -> c64 {
        match self {
            Quantity::Receptance => c64::new(1.0, 0.0),
            Quantity::Mobility => c64::new(0.0, omega),
            Quantity::Accelerance => c64::new(-omega * omega, 0.0),
        }
    }

    /// Power `k` of `iω` relative to receptance.
    pub fn order(self) -> i32 {
        match self {
            Quantity::Receptance => 0,
            Quantity::Mobility => 1,
            Quantity::Accelerance => 2,
        }
    }
}

impl std::str::FromStr for Quantity {
    type Err = CoreError;
    fn from_str(s: &str) -> Result<Self, CoreError> {
        match s.trim().to_ascii_lowercase().as_str() {
            "receptance" | "displacement" | "compliance" => Ok(Quantity::Receptance),
            "mobility" | "velocity" => Ok(Quantity::Mobility),
            "accelerance" | "inertance" | "acceleration" => Ok(Quantity::Accelerance),
            _ => Err(CoreError::Unknown {
                kind: "quantity",
                value: s.into(),
                expected: Quantity::NAMES,
            }),
        }
    }
}

/// Checks a frequency axis: non-empty, finite, non-negative and strictly increasing.
pub fn validate_frequency_axis(hz: &[f64]) -> Result<(), CoreError> {
    if hz.is_empty() {
        return Err(CoreError::FrequencyAxis("no spectral lines".into()));
    }
    for (i, f) in hz.iter().enumerate() {
        if !f.is_finite() || *f < 0.0 {
            return Err(CoreError::FrequencyAxis(format!(
                "line {i}: frequency {f} Hz is not a finite non-negative number"
            )));
        }
        if i > 0 && *f <= hz[i - 1] {
            return Err(CoreError::FrequencyAxis(format!(
                "line {i}: frequency {f} Hz does not increase (previous {} Hz)",
                hz[i - 1]
            )));
        }
    }
    Ok(())
}

/// FRFs of one test: values indexed `[excitation][channel][line]` in that memory order,
/// excitation and channel order as in the [`crate::Geometry`].
#[derive(Debug, Clone, PartialEq)]
pub struct FrfSet {
    /// What the values are per newton (readers convert to receptance on the way in).
    pub quantity: Quantity,
    /// Spectral lines (Hz), strictly ascending.
    pub frequency_hz: Vec<f64>,
    /// Number of excitations (force inputs), the slowest index.
    pub n_excitations: usize,
    /// Number of response channels.
    pub n_channels: usize,
    /// The complex FRF values, `[excitation][channel][line]`, row-major; the quantity's units.
    pub values: Vec<c64>,
}

impl FrfSet {
    /// A zero-filled set of the given shape.
    pub fn zeros(
        quantity: Quantity,
        frequency_hz: Vec<f64>,
        n_excitations: usize,
        n_channels: usize,
    ) -> Self {
        let n = n_excitations * n_channels * frequency_hz.len();
        Self {
            quantity,
            frequency_hz,
            n_excitations,
            n_channels,
            values: vec![c64::new(0.0, 0.0); n],
        }
    }

    /// Number of spectral lines.
    pub fn n_lines(&self) -> usize {
        self.frequency_hz.len()
    }

    fn offset(&self, excitation: usize, channel: usize) -> usize {
        (excitation * self.n_channels + channel) * self.n_lines()
    }

    /// The FRF of one channel for one excitation.
    pub fn frf(&self, excitation: usize, channel: usize) -> &[c64] {
        let o = self.offset(excitation, channel);
        &self.values[o..o + self.n_lines()]
    }

    /// The FRF of one channel for one excitation, to write into.
    pub fn frf_mut(&mut self, excitation: usize, channel: usize) -> &mut [c64] {
        let o = self.offset(excitation, channel);
        let n = self.n_lines();
        &mut self.values[o..o + n]
    }

    /// All channels of one excitation (a SIMO data set), `[channel][line]`.
    pub fn excitation_block(&self, excitation: usize) -> &[c64] {
        let o = self.offset(excitation, 0);
        &self.values[o..o + self.n_channels * self.n_lines()]
    }

    /// The values fill excitations × channels × lines.
    fn check_shape(&self) -> Result<(), CoreError> {
        let expect = self.n_excitations * self.n_channels * self.n_lines();
        if self.values.len() != expect {
            return Err(CoreError::FrfShape(format!(
                "{} values for {} excitations × {} channels × {} lines (expected {expect})",
                self.values.len(),
                self.n_excitations,
                self.n_channels,
                self.n_lines()
            )));
        }
        Ok(())
    }

    /// Checks shape, axis and finiteness; errors name the excitation, channel and line.
    pub fn validate(&self) -> Result<(), CoreError> {
        validate_frequency_axis(&self.frequency_hz)?;
        self.check_shape()?;
        if let Some(i) = self
            .values
            .iter()
            .position(|v| !(v.re.is_finite() && v.im.is_finite()))
        {
            let nl = self.n_lines();
            let (e, c, l) = (
                i / (nl * self.n_channels),
                (i / nl) % self.n_channels,
                i % nl,
            );
            return Err(CoreError::FrfShape(format!(
                "excitation {e}, channel {c}, line {l} ({} Hz): value {} is not finite",
                self.frequency_hz[l], self.values[i]
            )));
        }
        Ok(())
    }

    /// The same data expressed as another quantity. Converting to receptance from
    /// mobility or accelerance at 0 Hz is undefined; such lines become an error.
    pub fn to_quantity(&self, target: Quantity) -> Result<FrfSet, CoreError> {
        if target == self.quantity {
            return Ok(self.clone());
        }
        let nl = self.n_lines();
        let mut factors = Vec::with_capacity(nl);
        for &f in &self.frequency_hz {
            let w = 2.0 * std::f64::consts::PI * f;
            let from = self.quantity.from_receptance_factor(w);
            let to = target.from_receptance_factor(w);
            if from.norm() == 0.0 {
                return Err(CoreError::FrequencyAxis(format!(
                    "cannot convert {} to {} at {f} Hz (division by iω = 0); drop the 0 Hz line first",
                    self.quantity.name(),
                    target.name()
                )));
            }
            factors.push(to / from);
        }
        let mut out = self.clone();
        out.quantity = target;
        for (i, v) in out.values.iter_mut().enumerate() {
            *v *= factors[i % nl];
        }
        Ok(out)
    }

    /// Restricts to lines with `fmin ≤ f ≤ fmax`.
    pub fn band(&self, fmin: f64, fmax: f64) -> FrfSet {
        self.band_of(0..self.n_excitations, fmin, fmax)
    }

    /// The excitations `which` restricted to lines with `fmin ≤ f ≤ fmax`.
    fn band_of(&self, which: std::ops::Range<usize>, fmin: f64, fmax: f64) -> FrfSet {
        let keep: Vec<usize> = (0..self.n_lines())
            .filter(|&l| self.frequency_hz[l] >= fmin && self.frequency_hz[l] <= fmax)
            .collect();
        let mut out = FrfSet::zeros(
            self.quantity,
            keep.iter().map(|&l| self.frequency_hz[l]).collect(),
            which.len(),
            self.n_channels,
        );
        for (k, e) in which.enumerate() {
            for c in 0..self.n_channels {
                let src = self.frf(e, c);
                for (d, &l) in out.frf_mut(k, c).iter_mut().zip(&keep) {
                    *d = src[l];
                }
            }
        }
        out
    }

    /// Keeps only the listed excitations, in that order.
    pub fn select_excitations(&self, which: &[usize]) -> FrfSet {
        let mut out = FrfSet::zeros(
            self.quantity,
            self.frequency_hz.clone(),
            which.len(),
            self.n_channels,
        );
        for (k, &e) in which.iter().enumerate() {
            let n = self.n_channels * self.n_lines();
            out.values[k * n..(k + 1) * n].copy_from_slice(self.excitation_block(e));
        }
        out
    }
}

impl FrfSet {
    /// The whole set of a source, excitation by excitation (for a method or an output that
    /// needs every value at once; a set in memory is copied).
    pub fn from_source(frf: &dyn FrfSource) -> Result<Self, CoreError> {
        let (ne, nc, nl) = (
            frf.n_excitations(),
            frf.n_channels(),
            frf.frequency_hz().len(),
        );
        let mut values = Vec::with_capacity(ne * nc * nl);
        for e in 0..ne {
            values.extend_from_slice(frf.excitation(e)?.block());
        }
        Ok(Self {
            quantity: frf.quantity(),
            frequency_hz: frf.frequency_hz().to_vec(),
            n_excitations: ne,
            n_channels: nc,
            values,
        })
    }
}

/// Largest excitation (channels × lines × 16 bytes) that the stages work on in parallel
/// with another. Working on one excitation holds a few copies of it at once (the values
/// read and their message text, the band, a fit's blocks or synthesis), so two in flight
/// beyond this would break issue 41's memory bound (2 × one excitation + 50 MB); above
/// it the excitations go one after the other (at 3 × 102,401 lines `modal-fit` 71 → 57 MB
/// for 1.44 → 1.62 s).
pub const PARALLEL_EXCITATION_BYTES: usize = 4 << 20;

/// Whether a stage may work on the excitations of `frf` in parallel
/// ([`PARALLEL_EXCITATION_BYTES`]).
pub fn excitations_in_parallel(frf: &dyn FrfSource) -> bool {
    frf.n_channels() * frf.frequency_hz().len() * 16 <= PARALLEL_EXCITATION_BYTES
}

/// The FRFs of a run as a stage reads them: the layout (quantity, axis, counts) at once,
/// each excitation's values when asked. A set in memory lends its own; a reader may
/// decode them from the file one excitation at a time, so that a stage which works per
/// excitation never holds the whole set (issue 41's memory bound).
pub trait FrfSource: Sync {
    /// What the values are per newton.
    fn quantity(&self) -> Quantity;
    /// Spectral lines (Hz), strictly ascending.
    fn frequency_hz(&self) -> &[f64];
    /// Number of excitations.
    fn n_excitations(&self) -> usize;
    /// Number of response channels.
    fn n_channels(&self) -> usize;
    /// Checks what can be checked without the values (a set in memory checks them too;
    /// a reader checks each excitation's as it decodes them).
    fn validate(&self) -> Result<(), CoreError>;
    /// The FRFs of excitation `e` (all channels), checked finite.
    fn excitation(&self, e: usize) -> Result<ExcitationFrf<'_>, CoreError>;
}

/// One excitation's FRFs from an [`FrfSource`]: excitation [`Self::index`] of
/// [`Self::set`] (the whole set when it was in memory, else a set of this one).
#[derive(Debug)]
pub struct ExcitationFrf<'a> {
    set: std::borrow::Cow<'a, FrfSet>,
    index: usize,
}

impl<'a> ExcitationFrf<'a> {
    /// Excitation `index` of a set in memory (borrowed, not copied).
    pub fn borrowed(set: &'a FrfSet, index: usize) -> Self {
        Self {
            set: std::borrow::Cow::Borrowed(set),
            index,
        }
    }
    /// A set holding one excitation.
    pub fn owned(set: FrfSet) -> Self {
        debug_assert_eq!(set.n_excitations, 1);
        Self {
            set: std::borrow::Cow::Owned(set),
            index: 0,
        }
    }
    /// The set the excitation's values live in.
    pub fn set(&self) -> &FrfSet {
        &self.set
    }
    /// The excitation's index in [`Self::set`].
    pub fn index(&self) -> usize {
        self.index
    }
    /// All channels, `[channel][line]`.
    pub fn block(&self) -> &[c64] {
        self.set.excitation_block(self.index)
    }
    /// This excitation's lines with `fmin ≤ f ≤ fmax`, as a set of one excitation
    /// ([`FrfSet::band`] of it, without copying the rest of a borrowed set).
    pub fn band(&self, fmin: f64, fmax: f64) -> FrfSet {
        self.set.band_of(self.index..self.index + 1, fmin, fmax)
    }
    /// A set of this excitation alone (moved when it is one, copied out of a borrowed set).
    pub fn into_set(self) -> FrfSet {
        match self.set {
            std::borrow::Cow::Owned(s) if s.n_excitations == 1 => s,
            set => set.select_excitations(&[self.index]),
        }
    }
}

impl FrfSource for FrfSet {
    fn quantity(&self) -> Quantity {
        self.quantity
    }
    fn frequency_hz(&self) -> &[f64] {
        &self.frequency_hz
    }
    fn n_excitations(&self) -> usize {
        self.n_excitations
    }
    fn n_channels(&self) -> usize {
        self.n_channels
    }
    fn validate(&self) -> Result<(), CoreError> {
        FrfSet::validate(self)
    }
    fn excitation(&self, e: usize) -> Result<ExcitationFrf<'_>, CoreError> {
        if e >= self.n_excitations {
            return Err(CoreError::FrfShape(format!(
                "excitation {e} of a set of {}",
                self.n_excitations
            )));
        }
        self.check_shape()?;
        Ok(ExcitationFrf::borrowed(self, e))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn three_excitations() -> FrfSet {
        let mut s = FrfSet::zeros(
            Quantity::Mobility,
            (0..40).map(|l| 0.1 + 0.25 * l as f64).collect(),
            3,
            4,
        );
        for (i, v) in s.values.iter_mut().enumerate() {
            *v = c64::new((i as f64 * 0.31).sin(), (i as f64 * 0.17).cos());
        }
        s
    }

    /// A set in memory lends each excitation as it is: its block, its band and a set of
    /// it alone are those of the whole set's excitation; an index beyond the set and a
    /// set whose values do not fill its shape are errors, not panics.
    #[test]
    fn a_set_lends_each_excitation_as_it_is() {
        let s = three_excitations();
        for e in 0..3 {
            let x = FrfSource::excitation(&s, e).unwrap();
            assert_eq!(x.block(), s.excitation_block(e));
            assert_eq!(x.band(1.0, 6.0), s.select_excitations(&[e]).band(1.0, 6.0));
            assert_eq!(x.band(1.0, 6.0).n_lines(), 20); // 1.1 … 5.85 Hz
            assert_eq!(x.into_set(), s.select_excitations(&[e]));
        }
        assert!(FrfSource::excitation(&s, 3).is_err());
        let mut short = s.clone();
        short.values.pop();
        assert!(FrfSource::excitation(&short, 0).is_err());
        let one = ExcitationFrf::owned(s.select_excitations(&[1]));
        assert_eq!((one.index(), one.block()), (0, s.excitation_block(1)));
    }

    #[test]
    fn quantity_conversion_round_trips() {
        let mut s = FrfSet::zeros(Quantity::Receptance, vec![0.5, 1.0, 2.0], 2, 3);
        for (i, v) in s.values.iter_mut().enumerate() {
            *v = c64::new(i as f64 + 1.0, -(i as f64) * 0.5);
        }
        let a = s.to_quantity(Quantity::Accelerance).unwrap();
        let w = 2.0 * std::f64::consts::PI * 2.0;
        assert!((a.frf(1, 2)[2] - s.frf(1, 2)[2] * (-w * w)).norm() < 1e-12);
        let back = a
            .to_quantity(Quantity::Mobility)
            .unwrap()
            .to_quantity(Quantity::Receptance)
            .unwrap();
        for (x, y) in back.values.iter().zip(&s.values) {
            assert!((x - y).norm() < 1e-12 * y.norm());
        }
    }

    #[test]
    fn zero_hz_conversion_to_receptance_is_refused() {
        let s = FrfSet::zeros(Quantity::Accelerance, vec![0.0, 1.0], 1, 1);
        assert!(s
            .to_quantity(Quantity::Receptance)
            .unwrap_err()
            .to_string()
            .contains("0 Hz"));
    }

    #[test]
    fn validate_names_bad_line() {
        let mut s = FrfSet::zeros(Quantity::Receptance, vec![1.0, 2.0], 2, 2);
        *s.frf_mut(1, 0).last_mut().unwrap() = c64::new(f64::NAN, 0.0);
        let e = s.validate().unwrap_err().to_string();
        assert!(e.contains("excitation 1, channel 0, line 1"), "{e}");
        let bad_axis = FrfSet::zeros(Quantity::Receptance, vec![1.0, 1.0], 1, 1);
        assert!(bad_axis.validate().is_err());
    }

    #[test]
    fn quantity_parses_names() {
        assert_eq!(
            "Inertance".parse::<Quantity>().unwrap(),
            Quantity::Accelerance
        );
        assert!("furlongs".parse::<Quantity>().is_err());
    }
}
