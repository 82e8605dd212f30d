//! An MCAP file's FRF set left in the file (`read_file_deferred`): the same record, the
//! same values one excitation at a time, the same output bytes; a file changed under it
//! is an error naming it; another writer's order falls back to the whole read.

use crate::roundtrip::{geometry, record};
use rbprops_core::{c64, Excitation, FrfSet, FrfSource, Quantity, Vec3};
use rbprops_formats::{mcap_file, topics, wire, JsonTopic, RunRecord};

/// `record()` with `n` excitations of `lines` lines (values that differ everywhere).
fn record_of(n: usize, lines: usize) -> RunRecord {
    let mut rec = record();
    let mut g = geometry();
    let first = g.excitations[0].clone();
    g.excitations = (0..n)
        .map(|k| Excitation {
            id: format!("F{k}"),
            position: first.position + Vec3::new(0.001 * k as f64, 0.0, 0.0),
            ..first.clone()
        })
        .collect();
    rec.set_geometry(&g);
    let mut frf = FrfSet::zeros(
        Quantity::Mobility,
        (0..lines).map(|l| 0.5 + l as f64 * 0.01).collect(),
        n,
        9,
    );
    for (i, v) in frf.values.iter_mut().enumerate() {
        *v = c64::new((i as f64 * 0.37).sin(), (i as f64 * 1e-3).cos() * 1e-9);
    }
    rec.frf = Some(frf);
    rec
}

/// Reads `rec` written to a file both ways and checks that they agree, value for value
/// and byte for byte when written again.
fn agrees(rec: &RunRecord) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    std::fs::write(&path, mcap_file::write(rec).unwrap()).unwrap();
    let (whole, notes, sha) = mcap_file::read_file_checked(&path, "run.mcap").unwrap();
    let (lean, deferred, lean_notes, lean_sha) =
        mcap_file::read_file_deferred(&path, "run.mcap").unwrap();
    let d = deferred.expect("rbprops' own file is read deferred");
    let set = whole.frf.as_ref().unwrap();
    assert!(lean.frf.is_none());
    assert_eq!((lean_notes, lean_sha), (notes, sha));
    assert_eq!(lean.topics, whole.topics);
    assert_eq!(
        (d.n_excitations(), d.n_channels()),
        (set.n_excitations, set.n_channels)
    );
    assert_eq!(
        (d.quantity(), d.frequency_hz()),
        (set.quantity, &set.frequency_hz[..])
    );
    // In reverse order: each is found from its own place, not from the reading's order.
    for e in (0..set.n_excitations).rev() {
        let x = d.excitation(e).unwrap();
        assert_eq!(x.block(), set.excitation_block(e), "excitation {e}");
    }
    assert_eq!(&rbprops_core::FrfSet::from_source(&d).unwrap(), set);
    let again = mcap_file::write_to_with(&lean, Some(&d), std::io::Cursor::new(Vec::new()))
        .unwrap()
        .into_inner();
    assert!(
        again == mcap_file::write(&whole).unwrap(),
        "written bytes differ"
    );
    // Into a sink that cannot seek (stdout on a pipe), chunk by chunk: the same bytes.
    let streamed = mcap_file::write_stream_with(&lean, Some(&d), Vec::new()).unwrap();
    assert!(again == streamed, "streamed bytes differ");
}

#[test]
fn deferred_excitations_are_the_whole_reads_in_one_chunk_and_across_many() {
    // Two messages in one chunk (the second found by its ordinal) …
    agrees(&record());
    // … and 40 messages of 270 kB of values over many chunks.
    agrees(&record_of(40, 1500));
}

#[test]
fn a_file_changed_after_it_was_read_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    std::fs::write(&path, mcap_file::write(&record_of(6, 400)).unwrap()).unwrap();
    let (_, d, _, _) = mcap_file::read_file_deferred(&path, "run.mcap").unwrap();
    let d = d.unwrap();
    assert!(d.excitation(3).is_ok());
    std::fs::write(&path, mcap_file::write(&record_of(7, 300)).unwrap()).unwrap();
    let e = d.excitation(3).unwrap_err().to_string();
    assert!(
        e.contains("run.mcap") && e.contains("excitation 'F3'"),
        "{e}"
    );
    assert!(e.contains("changed"), "{e}");
    std::fs::write(&path, b"").unwrap();
    let e = d.excitation(0).unwrap_err().to_string();
    assert!(e.contains("run.mcap") && e.contains("'F0'"), "{e}");
}

#[test]
fn frf_messages_before_their_axis_are_read_whole() {
    // Another writer's order: the FRF messages as a topic before the axis.
    let full = record();
    let set = full.frf.clone().unwrap();
    let g = geometry();
    let mut rec = full.clone();
    rec.frf = None;
    let frf_msgs: Vec<wire::FrfMsg> = g
        .excitations
        .iter()
        .enumerate()
        .map(|(e, x)| wire::FrfMsg {
            excitation: x.id.clone(),
            values_f64le: wire::encode_values(set.excitation_block(e)),
        })
        .collect();
    rec.set(topics::FRF, &frf_msgs);
    rec.set(topics::FRF_AXIS, &[wire::frf_axis(&set, &g)]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("other.mcap");
    std::fs::write(&path, mcap_file::write(&rec).unwrap()).unwrap();
    let (lean, d, _, _) = mcap_file::read_file_deferred(&path, "other.mcap").unwrap();
    assert!(d.is_none());
    assert_eq!(lean.frf.as_ref(), Some(&set));
    let no_frf: Vec<&JsonTopic> = lean.topics.iter().collect();
    assert!(no_frf
        .iter()
        .all(|t| t.name != topics::FRF && t.name != topics::FRF_AXIS));
}

/// Another writer's layouts of the same messages: every message a top-level record (no
/// chunks), and chunks closed at 4 kB (each FRF message, 43 kB, alone in its chunk).
/// Each excitation is found again where it lies.
#[test]
fn unchunked_and_small_chunked_files_are_read_one_excitation_at_a_time() {
    let rec = record_of(5, 300);
    let bytes = mcap_file::write(&rec).unwrap();
    let messages: Vec<mcap::Message> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .collect();
    for opts in [
        mcap::WriteOptions::new().use_chunks(false),
        mcap::WriteOptions::new().chunk_size(Some(4096)),
    ] {
        let mut w = opts.create(std::io::Cursor::new(Vec::new())).unwrap();
        for m in &messages {
            w.write(m).unwrap();
        }
        w.finish().unwrap();
        let other = w.into_inner().into_inner();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("other.mcap");
        std::fs::write(&path, &other).unwrap();
        let (whole, _, _) = mcap_file::read_file_checked(&path, "other.mcap").unwrap();
        let (lean, d, _, _) = mcap_file::read_file_deferred(&path, "other.mcap").unwrap();
        let (d, set) = (d.expect("deferred"), whole.frf.as_ref().unwrap());
        assert_eq!(set, rec.frf.as_ref().unwrap());
        assert_eq!(lean.topics, whole.topics);
        for e in (0..5).rev() {
            assert_eq!(d.excitation(e).unwrap().block(), set.excitation_block(e));
        }
    }
}

/// With a scratch file ([`mcap_file::DeferredFrf::keep_values_in`]) an excitation asked
/// for again comes back from its raw copy with the same values, bit for bit (signed zeros,
/// subnormals and the extremes included), whatever the order of the asking; and the copy
/// is made only from the second time (a stage that reads each excitation once writes
/// nothing).
#[test]
fn excitations_asked_for_again_come_back_from_the_scratch_file_unchanged() {
    let mut rec = record_of(6, 300);
    let extremes = [
        0.0,
        -0.0,
        f64::MIN_POSITIVE / 8.0,
        f64::MAX,
        -f64::MAX,
        1e-300,
    ];
    let frf = rec.frf.as_mut().unwrap();
    let per = frf.excitation_block(0).len();
    for (i, x) in extremes.iter().enumerate() {
        frf.values[i] = c64::new(*x, -*x);
        frf.values[5 * per + i] = c64::new(-*x, *x);
    }
    let set = rec.frf.clone().unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("run.mcap");
    std::fs::write(&path, mcap_file::write(&rec).unwrap()).unwrap();
    let (_, deferred, _, _) = mcap_file::read_file_deferred(&path, "run.mcap").unwrap();
    let mut d = deferred.unwrap();
    let scratch_path = dir.path().join("scratch");
    let scratch = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(true)
        .open(&scratch_path)
        .unwrap();
    d.keep_values_in(scratch);
    let bits = |b: &[c64]| -> Vec<(u64, u64)> {
        b.iter().map(|z| (z.re.to_bits(), z.im.to_bits())).collect()
    };
    for e in [3, 0, 5] {
        d.excitation(e).unwrap();
    }
    assert_eq!(
        std::fs::metadata(&scratch_path).unwrap().len(),
        0,
        "read once: no copy"
    );
    for round in 0..3 {
        for e in [5, 2, 3, 0, 1, 4] {
            let x = d.excitation(e).unwrap();
            assert_eq!(
                bits(x.block()),
                bits(set.excitation_block(e)),
                "round {round}, excitation {e}"
            );
        }
    }
    let per_excitation = 16 * set.n_channels * set.frequency_hz.len();
    assert_eq!(
        std::fs::metadata(&scratch_path).unwrap().len() as usize,
        6 * per_excitation,
        "each excitation copied once"
    );
}
