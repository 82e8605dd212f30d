//! An MCAP file's FRF set left in the file: the record's other topics are read, every FRF
//! message is decoded and checked once and its place remembered, and a stage then asks
//! for one excitation at a time (issue 41: a stage that works per excitation holds one
//! excitation's values, not the set's).

use super::{
    check_message_count, check_message_order, read_exact_at, with_file_source, FrfMessages,
    FrfMsgText, FrfPlace,
};
use crate::wire::FrfAxisMsg;
use crate::{topics, FormatError, RunRecord};
use rbprops_core::{c64, CoreError, ExcitationFrf, FrfSet, FrfSource, Quantity};
use std::sync::Mutex;

/// The FRF set of an MCAP file, decoded one excitation at a time as it is asked for
/// ([`FrfSource`]). Every message was decoded and checked when the file was read
/// ([`read_file_deferred`]); reading one again checks its chunk's CRC again, and a file
/// changed meanwhile is an error naming it.
#[derive(Debug)]
pub struct DeferredFrf {
    file: String,
    handle: Mutex<std::fs::File>,
    axis: FrfAxisMsg,
    places: Vec<FrfPlace>,
    /// Raw copies of excitations asked for more than once ([`DeferredFrf::keep_values_in`]).
    scratch: Option<Mutex<Scratch>>,
}

/// Decoded values of the excitations asked for more than once.
#[derive(Debug)]
struct Scratch {
    /// Excitation `e`'s values as `re, im` pairs under key `e`.
    values: crate::scratch::ScratchValues,
    /// Times each excitation was asked for.
    asked: Vec<u32>,
}

/// [`super::read_file_checked`] with the FRF values left in the file: the record has no
/// FRF set and the [`DeferredFrf`] gives its excitations one at a time. When the file
/// cannot be read that way (FRF messages before their axis, another writer's order), the
/// record holds the set as [`super::read_file_checked`] gives it and there is no
/// [`DeferredFrf`]; likewise when the file has no FRFs.
pub fn read_file_deferred(
    path: &std::path::Path,
    file: &str,
) -> Result<(RunRecord, Option<DeferredFrf>, Vec<String>, String), FormatError> {
    let ((rec, frf, notes), sha256, handle) =
        with_file_source(path, file, |src| super::walk(src, file, true))?;
    let FrfMessages {
        axis,
        decoded_ids,
        pending,
        places,
        ..
    } = frf;
    let Some(axis) = axis else {
        return Ok((rec, None, notes, sha256));
    };
    if !pending.is_empty() {
        let (rec, notes, sha256) = super::read_file_checked(path, file)?;
        return Ok((rec, None, notes, sha256));
    }
    check_message_count(&rec, &axis, decoded_ids.len(), file)?;
    check_message_order(&axis, &decoded_ids, file)?;
    rbprops_core::frf::validate_frequency_axis(&axis.frequency_hz)
        .map_err(|e| FormatError::record(file, topics::FRF_AXIS, e))?;
    let deferred = DeferredFrf {
        file: file.into(),
        handle: Mutex::new(handle),
        axis,
        places,
        scratch: None,
    };
    Ok((rec, Some(deferred), notes, sha256))
}

impl DeferredFrf {
    /// From the second time an excitation is asked for, its decoded values are written to
    /// `file` (an unnamed temporary file the caller made) and read back from there: raw
    /// bytes instead of a chunk decompressed and a message decoded (2.3 ms for 9 channels
    /// × 1,601 lines). For a stage that passes over a set-up's excitations again and again
    /// without holding them (the poly-reference fit of many excitations, issue 41); the
    /// copies live in the page cache, not in the stage's memory. A failed write leaves
    /// the excitation to be decoded again.
    pub fn keep_values_in(&mut self, file: std::fs::File) {
        self.scratch = Some(Mutex::new(Scratch {
            values: crate::scratch::ScratchValues::new(file),
            asked: vec![0; self.places.len()],
        }));
    }

    /// Excitation `e`'s values from the scratch file, or decoded (and kept there when
    /// asked for before).
    fn values(&self, e: usize) -> Result<Vec<c64>, FormatError> {
        let Some(scratch) = &self.scratch else {
            return self.decoded(e);
        };
        {
            let mut s = scratch.lock().unwrap_or_else(|p| p.into_inner());
            s.asked[e] = s.asked[e].saturating_add(1);
            if let Some(Ok(v)) = s.values.get(e, None) {
                return Ok(v.chunks_exact(2).map(|p| c64::new(p[0], p[1])).collect());
            }
        }
        let v = self.decoded(e)?;
        let mut s = scratch.lock().unwrap_or_else(|p| p.into_inner());
        if s.asked[e] > 1 && s.values.count(e).is_none() {
            // A failed write leaves the excitation to be decoded again.
            let _ = s.values.put(e, v.iter().flat_map(|z| [z.re, z.im]));
        }
        Ok(v)
    }

    /// Excitation `e`'s values, `[channel][line]`, read again from the file.
    fn decoded(&self, e: usize) -> Result<Vec<c64>, FormatError> {
        let id = &self.axis.excitations[e];
        let record = format!("{} excitation '{id}'", topics::FRF);
        let changed = |detail: String| {
            FormatError::record(
                &self.file,
                &record,
                format!("cannot be read again ({detail}); was the file changed while it was used?"),
            )
        };
        let data = self.message(self.places[e]).map_err(changed)?;
        let msg: FrfMsgText = serde_json::from_slice(&data)
            .map_err(|e| changed(format!("the message no longer decodes: {e}")))?;
        if msg.excitation != *id {
            return Err(changed(format!(
                "excitation '{}' in its place",
                msg.excitation
            )));
        }
        let (_, v) =
            FrfMessages::decode(&self.axis, e, msg.excitation, &msg.values_f64le, &self.file)?;
        super::check_finite(&v, id, &self.axis, &self.file)?;
        Ok(v)
    }

    /// The data of the message at `place`: its record is read from the file and fed to
    /// the MCAP reader (its chunk CRC checked again) until the message is reached.
    fn message(&self, place: FrfPlace) -> Result<Vec<u8>, String> {
        use mcap::records::Record;
        use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
        let mut f = self.handle.lock().unwrap_or_else(|p| p.into_inner());
        let mut head = [0u8; 9];
        read_exact_at(&mut f, place.record, &mut head).map_err(|e| e.to_string())?;
        let body = u64::from_le_bytes(head[1..].try_into().expect("eight bytes"));
        let file_len = f.metadata().map_err(|e| e.to_string())?.len();
        if body > file_len {
            return Err(format!("record at byte {} runs past the end", place.record));
        }
        let end = place.record + 9 + body as usize;
        let mut reader = LinearReader::new_with_options(
            LinearReaderOptions::default()
                .with_skip_start_magic(true)
                .with_record_length_limit(body as usize + (256 << 20))
                .with_prevalidate_chunk_crcs(true)
                .with_validate_data_section_crc(false)
                .with_validate_summary_section_crc(false),
        );
        let mut pos = place.record;
        let mut seen = 0usize;
        while let Some(event) = reader.next_event() {
            match event.map_err(super::crc_detail)? {
                LinearReadEvent::ReadRequest(need) => {
                    let n = need.min(end - pos);
                    if n == 0 {
                        break;
                    }
                    read_exact_at(&mut f, pos, reader.insert(n)).map_err(|e| e.to_string())?;
                    reader.notify_read(n);
                    pos += n;
                }
                LinearReadEvent::Record { opcode, data } => {
                    if let Ok(Record::Message { header, data }) = mcap::parse_record(opcode, data) {
                        if header.channel_id == place.channel {
                            if seen == place.ordinal {
                                return Ok(data.into_owned());
                            }
                            seen += 1;
                        }
                    }
                }
            }
        }
        Err(format!(
            "no such message in the record at byte {}",
            place.record
        ))
    }
}

impl FrfSource for DeferredFrf {
    fn quantity(&self) -> Quantity {
        self.axis.quantity
    }
    fn frequency_hz(&self) -> &[f64] {
        &self.axis.frequency_hz
    }
    fn n_excitations(&self) -> usize {
        self.places.len()
    }
    fn n_channels(&self) -> usize {
        self.axis.channels.len()
    }
    fn validate(&self) -> Result<(), CoreError> {
        // The values were checked as the file was read; each is checked again as it is.
        rbprops_core::frf::validate_frequency_axis(&self.axis.frequency_hz)
    }
    fn excitation(&self, e: usize) -> Result<ExcitationFrf<'_>, CoreError> {
        if e >= self.places.len() {
            return Err(CoreError::FrfShape(format!(
                "excitation {e} of a set of {}",
                self.places.len()
            )));
        }
        let values = self
            .values(e)
            .map_err(|err| CoreError::FrfSource(err.to_string()))?;
        Ok(ExcitationFrf::owned(FrfSet {
            quantity: self.axis.quantity,
            frequency_hz: self.axis.frequency_hz.clone(),
            n_excitations: 1,
            n_channels: self.axis.channels.len(),
            values,
        }))
    }
}
