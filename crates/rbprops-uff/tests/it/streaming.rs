//! `parse_reader` (one dataset at a time, as `frf-est` reads a recording) against `parse`
//! (the whole file in memory): the same datasets, the same errors with the same line
//! numbers, and every byte passed to the digest, on every UFF fixture of the repository
//! and on each of them cut short at several places.

use std::path::{Path, PathBuf};

fn uff_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            uff_files(&p, out);
        } else if matches!(p.extension().and_then(|e| e.to_str()), Some("uff" | "unv")) {
            out.push(p);
        }
    }
}

/// Both readers on `bytes`: equal files or equal error messages; the bytes seen are the
/// input.
fn same(bytes: &[u8], name: &str) {
    let whole = rbprops_uff::parse(bytes, name);
    let mut seen = Vec::new();
    let streamed =
        rbprops_uff::parse_reader(std::io::BufReader::with_capacity(97, bytes), name, |b| {
            seen.extend_from_slice(b)
        });
    match (whole, streamed) {
        (Ok(a), Ok(b)) => {
            assert!(a == b, "{name}: the datasets differ");
            assert!(seen == bytes, "{name}: the digest did not see every byte");
        }
        (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "{name}"),
        (a, b) => panic!("{name}: parse {:?}, parse_reader {:?}", a.err(), b.err()),
    }
}

#[test]
fn streaming_reader_equals_the_whole_file_reader() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fixtures");
    let mut files = Vec::new();
    uff_files(&root, &mut files);
    files.sort();
    assert!(files.len() >= 20, "{} UFF fixtures", files.len());
    for f in &files {
        let bytes = std::fs::read(f).unwrap();
        let name = f.file_name().unwrap().to_string_lossy().to_string();
        same(&bytes, &name);
        // Cut short anywhere: inside a header, inside ASCII or binary data, at a delimiter.
        for k in 1..8 {
            let cut = bytes.len() * k / 8 + k;
            same(
                &bytes[..cut.min(bytes.len())],
                &format!("{name} cut at {cut}"),
            );
        }
        same(b"\n\n   \n", "blank");
        same(b"text\n    -1\n", "stray text");
    }
}
