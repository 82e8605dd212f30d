//! Bad input: clear errors naming the file, the dataset and the field; never a panic.

use crate::common::{campaign, even_axis, Spec};
use proptest::prelude::*;
use rbprops_core::Quantity;
use rbprops_uff::{from_campaign, parse, to_campaign, UffError, WriteOptions};

const NAME: &str = "lab/run7.unv";

fn small(binary: bool) -> Vec<u8> {
    let spec = Spec {
        point_ids: vec!["1".into(), "2".into(), "3".into(), "4".into()],
        misoriented: false,
        quantity: Quantity::Accelerance,
        frequency_hz: even_axis(6, 0.5),
        seed: 99,
    };
    let (g, frf) = campaign(&spec);
    from_campaign(
        &g,
        &frf,
        &WriteOptions {
            binary,
            ..Default::default()
        },
    )
    .unwrap()
}

fn text(binary: bool) -> String {
    String::from_utf8(small(binary)).unwrap()
}

fn read(s: &[u8]) -> Result<(), UffError> {
    let uff = parse(s, NAME)?;
    to_campaign(&uff).map(|_| ())
}

fn err(s: &str) -> String {
    let e = read(s.as_bytes()).unwrap_err().to_string();
    assert!(e.starts_with(NAME), "error does not name the file: {e}");
    e
}

/// Index of the `k`-th (0-based) line starting with `prefix` (after the header lines).
fn nth_line_index(lines: &[&str], prefix: &str, k: usize) -> usize {
    lines
        .iter()
        .enumerate()
        .filter(|(_, l)| l.starts_with(prefix))
        .nth(k)
        .map(|(i, _)| i)
        .unwrap()
}

fn replace_line(s: &str, idx: usize, new: &str) -> String {
    let mut lines: Vec<String> = s.lines().map(String::from).collect();
    lines[idx] = new.to_string();
    lines.join("\n") + "\n"
}

#[test]
fn valid_small_files_read() {
    read(&small(false)).unwrap();
    read(&small(true)).unwrap();
}

#[test]
fn truncated_files_are_errors_not_panics() {
    for binary in [false, true] {
        let b = small(binary);
        for cut in (1..b.len()).step_by(7) {
            match read(&b[..cut]) {
                Err(e) => assert!(e.to_string().starts_with(NAME), "{e}"),
                // A cut right at a dataset boundary leaves a smaller, valid campaign
                // (fewer channels/excitations); a cut inside a dataset never reads.
                Ok(()) => {
                    let text = String::from_utf8_lossy(&b[..cut]);
                    let tail = text.trim_end_matches([' ', '\n']);
                    assert!(
                        tail.ends_with("    -1"),
                        "cut at {cut} of {} reads",
                        b.len()
                    );
                }
            }
        }
    }
    let s = text(false);
    let cut = &s[..s.len() - 200];
    let e = err(cut);
    assert!(e.contains("truncated"), "{e}");
    assert!(e.contains("dataset #"), "{e}");
}

#[test]
fn truncated_binary_names_the_byte_count() {
    let b = small(true);
    let e = read(&b[..b.len() - 30]).unwrap_err().to_string();
    assert!(
        e.contains("type 58") && e.contains("number of bytes"),
        "{e}"
    );
}

#[test]
fn wrong_field_widths_are_named() {
    let s = text(false);
    let lines: Vec<&str> = s.lines().collect();
    // The first data line of the first dataset 58: shift its fields by one column and
    // drop its last value. (A shift alone reads, as blank-separated values whose count
    // matches record 7; with a value missing the counts disagree and nothing is guessed.)
    let r7 = nth_line_index(&lines, "         6         6         1", 0);
    let data = r7 + 5;
    let shifted = format!(" {}", &lines[data][..60]);
    let e = err(&replace_line(&s, data, &shifted));
    assert!(e.contains("record 12"), "{e}");
    assert!(e.contains(&format!("line {}", data + 1)), "{e}");
    assert!(e.contains("dataset #3 (type 58"), "{e}");
    // Record 6 written with 4-column node fields.
    let r6 = r7 - 1;
    let squeezed = format!("{}{}", &lines[r6][..38], &lines[r6][41..]);
    let e = err(&replace_line(&s, r6, &squeezed));
    assert!(e.contains("record 6"), "{e}");
}

#[test]
fn unknown_type_codes_are_named() {
    let s = text(false);
    let lines: Vec<&str> = s.lines().collect();
    let r7 = nth_line_index(&lines, "         6         6         1", 0);
    let r6 = r7 - 1;
    // Function type 99.
    let e = err(&replace_line(&s, r6, &format!("   99{}", &lines[r6][5..])));
    assert!(e.contains("function type") && e.contains("99"), "{e}");
    // Ordinate data type 7.
    let e = err(&replace_line(
        &s,
        r7,
        &format!("         7{}", &lines[r7][10..]),
    ));
    assert!(
        e.contains("ordinate data type") && e.contains("unknown code 7"),
        "{e}"
    );
    // Response direction 9.
    let bad = format!("{}   9{}", &lines[r6][..51], &lines[r6][55..]);
    let e = err(&replace_line(&s, r6, &bad));
    assert!(e.contains("response direction") && e.contains("9"), "{e}");
    // Rotational response direction 4 is valid UFF but not a channel for us.
    let bad = format!("{}   4{}", &lines[r6][..51], &lines[r6][55..]);
    let e = err(&replace_line(&s, r6, &bad));
    assert!(e.contains("not a translation"), "{e}");
    // Numerator data type 15 (pressure).
    let r9 = r7 + 2;
    let e = err(&replace_line(
        &s,
        r9,
        &format!("        15{}", &lines[r9][10..]),
    ));
    assert!(e.contains("record 9") && e.contains("data type 15"), "{e}");
    // Units code 12.
    let u = nth_line_index(&lines, "         1SI", 0);
    let e = err(&replace_line(
        &s,
        u,
        &format!("        12{}", &lines[u][10..]),
    ));
    assert!(e.contains("units code 12") && e.contains("type 164"), "{e}");
    // An unknown units label on a typed axis is a warning (record 9 decides); on an
    // untyped axis (data type 0) nothing determines the unit: an error.
    let furlong = lines[r9].replace("m/s^2 ", "furlong");
    let uff = parse(replace_line(&s, r9, &furlong).as_bytes(), NAME).unwrap();
    let read = rbprops_uff::read_campaign(&uff, &Default::default()).unwrap();
    assert!(
        read.warnings
            .iter()
            .any(|w| w.contains("'furlong' is not used (unknown unit 'furlong')")),
        "{:?}",
        read.warnings
    );
    let e = err(&replace_line(
        &s,
        r9,
        &format!("         0{}", &furlong[10..]),
    ));
    assert!(
        e.contains("furlong") && e.contains("nothing determines the unit"),
        "{e}"
    );
}

#[test]
fn campaign_errors_name_datasets_and_pairs() {
    let s = text(false);
    let blocks: Vec<&str> = s.split_inclusive("    -1\n").collect();
    // Datasets are [open, body+close] pairs of pieces; dataset k (1-based) = pieces 2k-2, 2k-1.
    let dataset = |k: usize| format!("{}{}", blocks[2 * k - 2], blocks[2 * k - 1]);
    let n = blocks.len() / 2;
    // Datasets 1, 2 are units and nodes. Drop the 5th FRF (dataset 7): a missing pair.
    let without: String = (1..=n).filter(|&k| k != 7).map(dataset).collect();
    let e = err(&without);
    assert!(
        e.contains("no FRF for channel '2:y'") && e.contains("excitation 'F1'"),
        "{e}"
    );
    // Duplicate the 5th FRF dataset.
    let dup: String = (1..=n).map(dataset).chain([dataset(7)]).collect();
    let e = err(&dup);
    assert!(
        e.contains("dataset #7") && e.contains(&format!("dataset #{}", n + 1)),
        "{e}"
    );
    // A different abscissa in dataset 6 (increment 0.25 instead of 0.5).
    let six = dataset(6).replace("          0.5  0.00000E+00", "         0.25  0.00000E+00");
    assert_ne!(six, dataset(6));
    let changed: String = (1..=n)
        .map(|k| if k == 6 { six.clone() } else { dataset(k) })
        .collect();
    let e = err(&changed);
    assert!(
        e.contains("dataset #3") && e.contains("dataset #6") && e.contains("abscissa"),
        "{e}"
    ); // Dataset 5 holds a mobility among accelerances.
    let five = dataset(5).replace(
        "        12    1    0    0 Acceleration         m/s^2 ",
        "        11    1    0    0 Velocity             m/s   ",
    );
    assert_ne!(five, dataset(5));
    let mixed: String = (1..=n)
        .map(|k| if k == 5 { five.clone() } else { dataset(k) })
        .collect();
    let e = err(&mixed);
    assert!(
        e.contains("dataset #3") && e.contains("dataset #5") && e.contains("mobility"),
        "{e}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn any_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let _ = read(&bytes);
    }

    #[test]
    fn delimited_garbage_never_panics(
        number in prop_oneof![Just("58"), Just("58b"), Just("15"), Just("2411"), Just("164"), Just("2420"), Just("18")],
        body in proptest::collection::vec("[ 0-9.E+-]{0,90}", 0..20),
    ) {
        let s = format!("    -1\n{number:>6}\n{}\n    -1\n", body.join("\n"));
        let _ = read(s.as_bytes());
    }

    #[test]
    fn mutated_valid_files_never_panic(
        binary in any::<bool>(),
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>(), 0u8..3), 1..8),
    ) {
        let mut b = small(binary);
        for (at, byte, kind) in edits {
            let i = at.index(b.len());
            match kind {
                0 => b[i] = byte,
                1 => { b.remove(i); }
                _ => b.insert(i, byte),
            }
        }
        if let Err(e) = read(&b) {
            prop_assert!(e.to_string().starts_with(NAME));
        }
    }
}
