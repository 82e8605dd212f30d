//! The bands of one set-up's excitations, as the poly-reference fit reads them: held
//! when they are small, else extracted again from the FRF source on every pass, so
//! that a set-up of many excitations is never held whole (issue 41: 192 excitations ×
//! 1,601 lines × 9 channels are 44 MB of bands, and the fit held them through its
//! sweeps, refinement and shape fit).
//!
//! Every pass of the fit goes through [`Bands`] one excitation at a time, so held and
//! read-again bands give the same arithmetic, bit for bit; a pass that pairs
//! excitations (the principal references' Gram matrix) holds
//! [`Bands::held_at_once`] of them.

use crate::band::BandData;
use crate::ModalError;
use rbprops_core::{FrfSource, Geometry};
use std::borrow::Cow;

/// A set-up's bands, one excitation at a time.
pub(crate) trait Bands: Sync {
    /// Number of excitations.
    fn len(&self) -> usize;
    /// Excitation `i`'s band.
    fn band(&self, i: usize) -> Result<Cow<'_, BandData>, ModalError>;
    /// How many bands of `bytes` each a pass may hold at once (at least 1).
    fn held_at_once(&self, bytes: usize) -> usize;
}

impl Bands for Vec<&BandData> {
    fn len(&self) -> usize {
        Vec::len(self)
    }
    fn band(&self, i: usize) -> Result<Cow<'_, BandData>, ModalError> {
        Ok(Cow::Borrowed(self[i]))
    }
    fn held_at_once(&self, _bytes: usize) -> usize {
        Vec::len(self).max(1)
    }
}

impl Bands for Vec<BandData> {
    fn len(&self) -> usize {
        Vec::len(self)
    }
    fn band(&self, i: usize) -> Result<Cow<'_, BandData>, ModalError> {
        Ok(Cow::Borrowed(&self[i]))
    }
    fn held_at_once(&self, _bytes: usize) -> usize {
        Vec::len(self).max(1)
    }
}

/// Bytes of bands a set-up holds whole, and that a pass pairing excitations holds at
/// once: above it they are extracted again from the source for each pass (from a
/// scratch copy when the source keeps one, `DeferredFrf::keep_values_in`: 0.1 ms an
/// excitation of 9 channels × 1,601 lines against 2.3 ms decoded). 4 MB, a few times
/// one excitation of a long record, keeps the fit's peak within issue 41's bound (twice
/// one excitation's data plus 50 MB) whatever the number of excitations.
pub(crate) const HELD_BYTES: usize = 4 << 20;

/// The bands of the excitations `members` of an FRF source.
pub(crate) struct SetupBands<'a> {
    frf: &'a dyn FrfSource,
    geometry: &'a Geometry,
    members: &'a [usize],
    band_hz: Option<(f64, f64)>,
    /// Bytes of bands held whole, and held at once by a pass pairing them.
    held_bytes: usize,
    held: Held,
}

/// What a set-up's bands hold.
enum Held {
    /// Every band (they fit in the holding limit).
    All(Vec<BandData>),
    /// The first excitation's band alone (its axis is every band's).
    First(BandData),
}

impl<'a> SetupBands<'a> {
    /// Extracts the first band (and every band, when they fit in `held_bytes`:
    /// [`HELD_BYTES`] but in tests).
    pub fn new(
        geometry: &'a Geometry,
        frf: &'a dyn FrfSource,
        members: &'a [usize],
        band_hz: Option<(f64, f64)>,
        held_bytes: usize,
    ) -> Result<Self, ModalError> {
        let extract =
            |e: usize| BandData::extract_from(frf, e, band_hz, &geometry.excitations[e].id);
        let first = extract(members[0])?;
        let held = if bytes_of(&first) * members.len() <= held_bytes {
            let rest = members[1..].iter().map(|&e| extract(e));
            Held::All(
                std::iter::once(Ok(first))
                    .chain(rest)
                    .collect::<Result<_, _>>()?,
            )
        } else {
            Held::First(first)
        };
        Ok(Self {
            frf,
            geometry,
            members,
            band_hz,
            held_bytes,
            held,
        })
    }

    /// The first excitation's band.
    pub fn first(&self) -> &BandData {
        match &self.held {
            Held::All(bands) => &bands[0],
            Held::First(first) => first,
        }
    }
}

/// Bytes of a band's values.
pub(crate) fn bytes_of(b: &BandData) -> usize {
    b.channels.len() * b.n_lines() * std::mem::size_of::<rbprops_core::c64>()
}

impl Bands for SetupBands<'_> {
    fn len(&self) -> usize {
        self.members.len()
    }
    fn band(&self, i: usize) -> Result<Cow<'_, BandData>, ModalError> {
        match &self.held {
            Held::All(b) => Ok(Cow::Borrowed(&b[i])),
            Held::First(first) if i == 0 => Ok(Cow::Borrowed(first)),
            Held::First(_) => {
                let e = self.members[i];
                let id = &self.geometry.excitations[e].id;
                BandData::extract_from(self.frf, e, self.band_hz, id).map(Cow::Owned)
            }
        }
    }
    fn held_at_once(&self, bytes: usize) -> usize {
        (self.held_bytes / bytes.max(1)).clamp(1, self.members.len())
    }
}

/// Bands read again (cloned) on every ask, `block` of them held at once by a pass
/// that pairs them: the other side of the tests that held and read-again bands fit
/// alike.
#[cfg(test)]
pub(crate) struct ReadAgain<'a> {
    pub bands: &'a [BandData],
    pub block: usize,
}

#[cfg(test)]
impl Bands for ReadAgain<'_> {
    fn len(&self) -> usize {
        self.bands.len()
    }
    fn band(&self, i: usize) -> Result<Cow<'_, BandData>, ModalError> {
        Ok(Cow::Owned(self.bands[i].clone()))
    }
    fn held_at_once(&self, _bytes: usize) -> usize {
        self.block
    }
}
