//! Splitting a universal file into datasets and parsing the typed ones.
//!
//! A dataset is framed by two delimiter lines holding `-1` (format I6). The line after
//! the opening delimiter holds the dataset number in columns 1–6; for a binary dataset
//! (58b) column 7 holds `b` followed by `I6,I6,I12,I12` = byte order (1 little, 2 big
//! endian), floating-point format (2 = IEEE 754), number of ASCII lines that follow and
//! number of binary bytes after them.

use crate::error::{DatasetLocation, UffError};
use crate::fortran::{check_tail, column, parse_int, parse_real};
use crate::model::*;
use rbprops_core::c64;

/// A line of the file: its bytes (without the line end) and its 1-based number.
#[derive(Clone, Copy)]
struct Line<'a> {
    bytes: &'a [u8],
    number: usize,
}

#[derive(Clone)]
struct Cursor<'a> {
    data: &'a [u8],
    pos: usize,
    next_line: usize,
}

impl<'a> Cursor<'a> {
    fn next(&mut self) -> Option<Line<'a>> {
        if self.pos >= self.data.len() {
            return None;
        }
        let rest = &self.data[self.pos..];
        let (mut line, adv) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        if let Some(stripped) = line.strip_suffix(b"\r") {
            line = stripped;
        }
        self.pos += adv;
        let number = self.next_line;
        self.next_line += 1;
        Some(Line {
            bytes: line,
            number,
        })
    }

    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let end = self.pos.checked_add(n)?;
        if end > self.data.len() {
            return None;
        }
        let out = &self.data[self.pos..end];
        self.pos = end;
        // Line numbers after binary data are approximate: count the newlines skipped.
        self.next_line += out.iter().filter(|&&b| b == b'\n').count();
        Some(out)
    }
}

fn is_delimiter(bytes: &[u8]) -> bool {
    trim_ascii(bytes) == b"-1"
}

fn trim_ascii(b: &[u8]) -> &[u8] {
    let start = b
        .iter()
        .position(|c| !c.is_ascii_whitespace())
        .unwrap_or(b.len());
    let end = b
        .iter()
        .rposition(|c| !c.is_ascii_whitespace())
        .map_or(start, |e| e + 1);
    &b[start..end.max(start)]
}

/// A record as text whose byte columns equal its character columns: non-ASCII bytes
/// become '?', so fixed-width fields can be cut by column.
fn ascii_text(b: &[u8]) -> String {
    b.iter()
        .map(|&c| if c.is_ascii() { c as char } else { '?' })
        .collect()
}

/// Decodes free text leniently: UTF-8 when the bytes are valid UTF-8, else Latin-1
/// (every byte is a character), so `²` written as the single Latin-1 byte 0xB2 reads as
/// `²`. Never fails.
pub fn decode_text(b: &[u8]) -> String {
    match std::str::from_utf8(b) {
        Ok(s) => s.to_string(),
        Err(_) => b.iter().map(|&c| c as char).collect(),
    }
}

/// Free text (ID lines, names): decoded leniently, trailing blanks removed.
fn free_text(b: &[u8]) -> String {
    decode_text(b).trim_end().to_string()
}

/// Context for errors inside one dataset.
pub(crate) struct Ctx<'f> {
    pub file: &'f str,
    pub at: DatasetLocation,
}

impl Ctx<'_> {
    pub fn err(&self, field: impl Into<String>, problem: impl Into<String>) -> UffError {
        UffError::Field {
            file: self.file.to_string(),
            at: self.at.clone(),
            field: field.into(),
            problem: problem.into(),
        }
    }
}

/// Parses a universal file. `file_name` is only used in error messages.
pub fn parse(bytes: &[u8], file_name: &str) -> Result<UffFile, UffError> {
    let mut datasets = Vec::new();
    let end_line = parse_into(bytes, file_name, 1, &mut datasets)?;
    finish(file_name, datasets, end_line)
}

/// The file of `datasets`, or the error of a file without any.
fn finish(file_name: &str, datasets: Vec<Dataset>, end_line: usize) -> Result<UffFile, UffError> {
    if datasets.is_empty() {
        return Err(UffError::Structure {
            file: file_name.to_string(),
            line: end_line,
            problem: "no datasets (a universal file starts each dataset with a line '    -1')"
                .into(),
        });
    }
    Ok(UffFile {
        file_name: file_name.to_string(),
        datasets,
    })
}

/// Parses a universal file from a reader, one dataset at a time, so that the file's bytes
/// are never all in memory (a recording of millions of samples): each dataset's bytes,
/// from the end of the one before to its closing delimiter, are gathered by their framing
/// (module docs; a binary dataset by its announced byte count, then up to the next
/// delimiter line) and parsed as [`parse`] parses them, with the same errors and line
/// numbers. `seen` gets every byte read, in order (for a digest of the file).
pub fn parse_reader(
    reader: impl std::io::BufRead,
    file_name: &str,
    seen: impl FnMut(&[u8]),
) -> Result<UffFile, UffError> {
    parse_reader_each(reader, file_name, seen, |_| Ok(()))
}

/// [`parse_reader`], handing each dataset to `each` as soon as it is parsed (before the
/// next is read): a caller can set a time history's samples aside there
/// ([`Function::samples_set_aside`]), so that the file's samples are never all held.
pub fn parse_reader_each(
    mut reader: impl std::io::BufRead,
    file_name: &str,
    mut seen: impl FnMut(&[u8]),
    mut each: impl FnMut(&mut Dataset) -> Result<(), UffError>,
) -> Result<UffFile, UffError> {
    let io = |e: std::io::Error| UffError::Structure {
        file: file_name.to_string(),
        line: 0,
        problem: format!("cannot read: {e}"),
    };
    let mut datasets = Vec::new();
    let mut chunk: Vec<u8> = Vec::new();
    let mut next_line = 1;
    loop {
        chunk.clear();
        // Appends one line (with its end) to the chunk; None at the end of the file.
        let line = |reader: &mut dyn std::io::BufRead, chunk: &mut Vec<u8>| {
            let start = chunk.len();
            let k = reader.read_until(b'\n', chunk).map_err(io)?;
            Ok::<_, UffError>((k > 0).then_some(start..chunk.len()))
        };
        // Up to the opening delimiter; anything else but blank lines is for the parser
        // to name.
        let mut opened = false;
        while let Some(r) = line(&mut reader, &mut chunk)? {
            let l = trim_ascii(&chunk[r]);
            if l == b"-1" {
                opened = true;
                break;
            }
            if !l.is_empty() {
                break;
            }
        }
        if opened {
            if let Some(r) = line(&mut reader, &mut chunk)? {
                let header = ascii_text(&chunk[r]);
                let binary = header.as_bytes().get(6).map(|c| c.to_ascii_lowercase()) == Some(b'b');
                let counts = (
                    parse_int(column(&header, 19, 12)),
                    parse_int(column(&header, 31, 12)),
                );
                if let (true, (Ok(n_ascii), Ok(n_bytes))) = (binary, counts) {
                    let mut ascii = Vec::new();
                    for _ in 0..n_ascii.clamp(0, 1000) {
                        match line(&mut reader, &mut chunk)? {
                            Some(r) => ascii.push(r),
                            None => break,
                        }
                    }
                    // When the announced count and the count record 7 implies differ
                    // (pyuff writes a third or half of the true count for complex data),
                    // `parse` tries both, looking past the data for the delimiter (which
                    // may follow the data on the same line): the rest of the file is
                    // read and parsed as `parse` would. Time histories are real and
                    // announce their true count, so they still stream.
                    let lines: Vec<Line> = ascii
                        .iter()
                        .map(|r| Line {
                            bytes: &chunk[r.clone()],
                            number: 0,
                        })
                        .collect();
                    let implied = (parse_int(column(&header, 0, 6)) == Ok(58))
                        .then(|| expected_58b_bytes(&lines))
                        .flatten();
                    let n_bytes = usize::try_from(n_bytes).unwrap_or(0);
                    let by_ref: &mut dyn std::io::BufRead = &mut reader;
                    if implied.is_some_and(|e| e != n_bytes) {
                        std::io::Read::read_to_end(by_ref, &mut chunk).map_err(io)?;
                    } else {
                        let mut data = std::io::Read::take(by_ref, n_bytes as u64);
                        std::io::Read::read_to_end(&mut data, &mut chunk).map_err(io)?;
                    }
                }
                // To the closing delimiter (after binary data: its line end, and the
                // rest of the data if the announced count was short, see `parse`).
                while let Some(r) = line(&mut reader, &mut chunk)? {
                    if is_delimiter(&chunk[r]) {
                        break;
                    }
                }
            }
        }
        seen(&chunk);
        let parsed = datasets.len();
        next_line = parse_into(&chunk, file_name, next_line, &mut datasets)?;
        for d in &mut datasets[parsed..] {
            each(d)?;
        }
        if !opened {
            // Only blank lines were left (stray text is the parser's error).
            return finish(file_name, datasets, next_line);
        }
    }
}

/// Parses the datasets in `bytes`, whose first line is line `first_line` of the file,
/// appending them to `datasets` (numbered on from its length). Returns the line number
/// after the last line.
fn parse_into(
    bytes: &[u8],
    file_name: &str,
    first_line: usize,
    datasets: &mut Vec<Dataset>,
) -> Result<usize, UffError> {
    let mut cur = Cursor {
        data: bytes,
        pos: 0,
        next_line: first_line,
    };
    let structure = |line: usize, problem: String| UffError::Structure {
        file: file_name.to_string(),
        line,
        problem,
    };
    loop {
        // Find the opening delimiter; only blank lines may come between datasets.
        let open = loop {
            match cur.next() {
                None => return Ok(cur.next_line),
                Some(l) if is_delimiter(l.bytes) => break l,
                Some(l) if trim_ascii(l.bytes).is_empty() => continue,
                Some(l) => {
                    return Err(structure(
                        l.number,
                        format!(
                            "text '{}' outside any dataset (expected the delimiter '    -1')",
                            free_text(trim_ascii(l.bytes))
                                .chars()
                                .take(40)
                                .collect::<String>()
                        ),
                    ))
                }
            }
        };
        let header = cur.next().ok_or_else(|| {
            structure(
                open.number,
                "file ends right after a dataset delimiter (truncated?)".into(),
            )
        })?;
        let htext = ascii_text(header.bytes);
        let number = parse_int(column(&htext, 0, 6))
            .map_err(|e| structure(header.number, format!("dataset number (columns 1-6): {e}")))?;
        let at = DatasetLocation {
            index: datasets.len() + 1,
            number,
            line: open.number,
        };
        let ctx = Ctx {
            file: file_name,
            at,
        };
        let binary_flag = htext.as_bytes().get(6).map(|c| c.to_ascii_lowercase()) == Some(b'b');
        let mut lines: Vec<Line> = Vec::new();
        let binary = if binary_flag {
            Some(binary_dataset(&mut cur, &htext, number, &ctx, &mut lines)?)
        } else {
            ascii_dataset(&mut cur, &ctx, &mut lines)?;
            None
        };
        let record = record_of(&ctx, number, &lines, binary)?;
        datasets.push(Dataset {
            location: ctx.at,
            record,
        });
    }
}

/// A binary dataset (58b) after its header line `htext`: the ASCII header lines (into
/// `lines`) and the binary data, found by the announced byte count (or, for pyuff's 58b,
/// the count record 7 implies) followed by the closing delimiter.
fn binary_dataset<'a>(
    cur: &mut Cursor<'a>,
    htext: &str,
    number: i64,
    ctx: &Ctx,
    lines: &mut Vec<Line<'a>>,
) -> Result<(BinaryLayout, &'a [u8]), UffError> {
    let field = |start, width, name: &str| {
        parse_int(column(htext, start, width))
            .map_err(|e| ctx.err(format!("binary header {name}"), e))
    };
    let order = field(7, 6, "field 3 (byte ordering)")?;
    let fp = field(13, 6, "field 4 (floating-point format)")?;
    let n_ascii = field(19, 12, "field 5 (number of ASCII lines)")?;
    let n_bytes = field(31, 12, "field 6 (number of bytes)")?;
    let little_endian = match order {
        1 => true,
        2 => false,
        o => {
            return Err(ctx.err(
                "binary header field 3 (byte ordering)",
                format!("unknown code {o} (1 little endian, 2 big endian)"),
            ))
        }
    };
    if fp != 2 {
        return Err(ctx.err(
            "binary header field 4 (floating-point format)",
            format!("code {fp} is not supported (only 2 = IEEE 754)"),
        ));
    }
    if !(0..=1000).contains(&n_ascii) {
        return Err(ctx.err(
            "binary header field 5 (number of ASCII lines)",
            format!("{n_ascii} is not a plausible line count"),
        ));
    }
    for k in 0..n_ascii {
        let l = cur.next().ok_or_else(|| {
            ctx.err(
                format!("ASCII line {} of {n_ascii}", k + 1),
                "file ends inside the dataset header (truncated)",
            )
        })?;
        lines.push(l);
    }
    let n = usize::try_from(n_bytes).map_err(|_| {
        ctx.err(
            "binary header field 6 (number of bytes)",
            format!("{n_bytes} is negative"),
        )
    })?;
    // pyuff (2.5) writes half the true byte count for complex 58b data; when the
    // announced count is not followed by the delimiter, the count implied by the
    // dataset's own record 7 is tried before giving up.
    let mut candidates = vec![n];
    if number == 58 {
        if let Some(e) = expected_58b_bytes(lines).filter(|&e| e != n) {
            candidates.push(e);
        }
    }
    let mut found = None;
    for &len in &candidates {
        let mut probe = cur.clone();
        let Some(data) = probe.take(len) else {
            continue;
        };
        // The line end after the data, and a stray extra line end some writers
        // add, may come before the closing delimiter (at most two blank lines:
        // anything else means the byte count is wrong).
        let mut close = probe.next();
        for _ in 0..2 {
            if matches!(close, Some(l) if trim_ascii(l.bytes).is_empty()) {
                close = probe.next();
            }
        }
        if matches!(close, Some(l) if is_delimiter(l.bytes)) {
            found = Some((data, probe));
            break;
        }
    }
    let Some((data, after)) = found else {
        return Err(ctx.err(
            "binary header field 6 (number of bytes)",
            if cur.data.len() - cur.pos < n {
                format!(
                    "the header announces {n} bytes but only {} remain (truncated)",
                    cur.data.len() - cur.pos
                )
            } else {
                format!("no closing '    -1' right after the announced {n} bytes of binary data")
            },
        ));
    };
    *cur = after;
    Ok((BinaryLayout { little_endian }, data))
}

/// An ASCII dataset's lines (into `lines`) up to its closing delimiter.
fn ascii_dataset<'a>(
    cur: &mut Cursor<'a>,
    ctx: &Ctx,
    lines: &mut Vec<Line<'a>>,
) -> Result<(), UffError> {
    loop {
        match cur.next() {
            Some(l) if is_delimiter(l.bytes) => return Ok(()),
            Some(l) => lines.push(l),
            None => {
                return Err(ctx.err(
                    "closing delimiter",
                    "file ends before the dataset's closing '    -1' (truncated)",
                ))
            }
        }
    }
}

/// The record of dataset `number` from its lines (and binary data): functions (58),
/// nodes (15, 2411), units (164), coordinate systems (2420, 18); any other kept as text.
fn record_of(
    ctx: &Ctx,
    number: i64,
    lines: &[Line],
    binary: Option<(BinaryLayout, &[u8])>,
) -> Result<Record, UffError> {
    Ok(match number {
        58 => Record::Function(Box::new(parse_58(ctx, lines, binary)?)),
        15 | 2411 if binary.is_none() => Record::Nodes(parse_nodes(ctx, number, lines)?),
        164 if binary.is_none() => Record::Units(parse_164(ctx, lines)?),
        2420 if binary.is_none() => Record::CoordinateSystems(parse_2420(ctx, lines)?),
        18 if binary.is_none() => Record::CoordinateSystems(parse_18(ctx, lines)?),
        _ => Record::Unknown {
            number,
            text: lines
                .iter()
                .map(|l| free_text(l.bytes))
                .collect::<Vec<_>>()
                .join("\n"),
        },
    })
}

/// The byte count a 58b dataset's records 7 implies (None if record 7 is unreadable).
fn expected_58b_bytes(lines: &[Line]) -> Option<usize> {
    let r7 = ascii_text(lines.get(6)?.bytes);
    let code = parse_int(column(&r7, 0, 10)).ok()?;
    let n = usize::try_from(parse_int(column(&r7, 10, 10)).ok()?).ok()?;
    let even = parse_int(column(&r7, 20, 10)).ok()? == 1;
    let t = OrdinateType::from_code(code)?;
    let per_point = match (t.is_complex(), even) {
        (false, true) => 1,
        (true, false) => 3,
        _ => 2,
    };
    let size = if t.is_double() { 8 } else { 4 };
    n.checked_mul(per_point)?.checked_mul(size)
}

/// Reads one fixed-width record. Columns count characters of the leniently decoded
/// line (a UTF-8 `²` is one column, as the writer meant it); numeric fields are cut from
/// an ASCII view of those characters, text fields from the characters themselves.
struct Rec<'c, 'f> {
    ctx: &'c Ctx<'f>,
    text: String,
    chars: Vec<char>,
    label: String,
}

impl<'c, 'f> Rec<'c, 'f> {
    fn new(
        ctx: &'c Ctx<'f>,
        line: Option<&Line>,
        label: impl Into<String>,
    ) -> Result<Self, UffError> {
        let label = label.into();
        let line = line.ok_or_else(|| ctx.err(&label, "missing (dataset truncated)"))?;
        let chars: Vec<char> = decode_text(line.bytes).chars().collect();
        Ok(Self {
            ctx,
            text: chars
                .iter()
                .map(|&c| if c.is_ascii() { c } else { '?' })
                .collect(),
            chars,
            label: format!("{label} (line {})", line.number),
        })
    }
    fn int(&self, start: usize, width: usize, name: &str) -> Result<i64, UffError> {
        parse_int(column(&self.text, start, width))
            .map_err(|e| self.ctx.err(format!("{} {name}", self.label), e))
    }
    fn int_or_zero(&self, start: usize, width: usize, name: &str) -> Result<i64, UffError> {
        if column(&self.text, start, width).trim().is_empty() {
            Ok(0)
        } else {
            self.int(start, width, name)
        }
    }
    fn real(&self, start: usize, width: usize, name: &str) -> Result<f64, UffError> {
        parse_real(column(&self.text, start, width))
            .map_err(|e| self.ctx.err(format!("{} {name}", self.label), e))
    }
    /// A text field (characters `[start, start + width)`), trimmed; never an error.
    fn text(&self, start: usize, width: usize) -> String {
        let s = start.min(self.chars.len());
        let e = start.saturating_add(width).min(self.chars.len());
        self.chars[s..e]
            .iter()
            .collect::<String>()
            .trim()
            .to_string()
    }
    fn end(&self, end: usize) -> Result<(), UffError> {
        check_tail(&self.text, end).map_err(|e| self.ctx.err(self.label.clone(), e))
    }
}

/// Reads `n` reals laid out `widths` per line (the last line may be short) starting at
/// line `first` of `lines`; returns the values and the index of the next line.
fn read_reals(
    ctx: &Ctx,
    lines: &[Line],
    first: usize,
    widths: &[usize],
    n: usize,
    what: &str,
) -> Result<(Vec<f64>, usize), UffError> {
    let mut out = Vec::new();
    let mut li = first;
    while out.len() < n {
        let line = lines.get(li).ok_or_else(|| {
            ctx.err(
                what,
                format!(
                    "found {} of {n} values before the dataset ended (truncated?)",
                    out.len()
                ),
            )
        })?;
        let text = ascii_text(line.bytes);
        let k = widths.len().min(n - out.len());
        let mut col = 0;
        for (j, &w) in widths[..k].iter().enumerate() {
            let v = parse_real(column(&text, col, w)).map_err(|e| {
                ctx.err(
                    format!(
                        "{what}, line {} value {} (columns {}-{})",
                        line.number,
                        j + 1,
                        col + 1,
                        col + w
                    ),
                    e,
                )
            })?;
            out.push(v);
            col += w;
        }
        check_tail(&text, col).map_err(|e| ctx.err(format!("{what}, line {}", line.number), e))?;
        li += 1;
    }
    Ok((out, li))
}

/// Record 12 of an ASCII dataset 58 read in its fixed columns; exactly `n_numbers`
/// values and nothing after them.
fn read_fixed_values(
    ctx: &Ctx,
    lines: &[Line],
    widths: &[usize],
    n: usize,
    n_numbers: usize,
) -> Result<Vec<f64>, UffError> {
    // Cheap guard against absurd counts before reading line by line.
    let lines_needed = n_numbers.div_ceil(widths.len());
    if lines_needed > lines.len().saturating_sub(11) {
        return Err(ctx.err(
            "record 12 (data values)",
            format!(
                "{n} values need {lines_needed} data lines, the dataset has {} (truncated?)",
                lines.len().saturating_sub(11)
            ),
        ));
    }
    let (v, next) = read_reals(ctx, lines, 11, widths, n_numbers, "record 12 (data values)")?;
    if let Some(extra) = lines[next..]
        .iter()
        .find(|l| !trim_ascii(l.bytes).is_empty())
    {
        return Err(ctx.err(
            format!("record 12 (data values), line {}", extra.number),
            format!("more data than the {n} values record 7 announces"),
        ));
    }
    Ok(v)
}

/// Every blank-separated number of the data lines, or None when some token is not a
/// number.
fn blank_separated_values(lines: &[Line]) -> Option<Vec<f64>> {
    let mut out = Vec::new();
    for l in lines {
        for tok in ascii_text(l.bytes).split_ascii_whitespace() {
            out.push(parse_real(tok).ok()?);
        }
    }
    Some(out)
}

fn parse_164(ctx: &Ctx, lines: &[Line]) -> Result<Units, UffError> {
    let r = Rec::new(ctx, lines.first(), "record 1")?;
    let code = r.int(0, 10, "field 1 (units code)")?;
    let description = r.text(10, 20);
    let temperature_mode = r.int_or_zero(30, 10, "field 3 (temperature mode)")?;
    r.end(40)?;
    if !(1..=9).contains(&code) {
        return Err(ctx.err(
            "record 1 field 1 (units code)",
            format!("unknown units code {code} (expected 1..9)"),
        ));
    }
    let (f, _) = read_reals(ctx, lines, 1, &[25, 25, 25], 4, "record 2 (unit factors)")?;
    Ok(Units {
        code,
        description,
        temperature_mode,
        length_factor: f[0],
        force_factor: f[1],
        temperature_factor: f[2],
        temperature_offset: f[3],
    })
}

fn parse_nodes(ctx: &Ctx, number: i64, lines: &[Line]) -> Result<NodeSet, UffError> {
    let mut nodes = Vec::new();
    let mut i = 0;
    while i < lines.len() {
        if trim_ascii(lines[i].bytes).is_empty() {
            i += 1;
            continue;
        }
        let r = Rec::new(
            ctx,
            lines.get(i),
            format!("node {} record 1", nodes.len() + 1),
        )?;
        let label = r.int(0, 10, "field 1 (node label)")?;
        let definition_cs = r.int_or_zero(10, 10, "field 2 (coordinate system)")?;
        let displacement_cs = r.int_or_zero(20, 10, "field 3 (displacement coordinate system)")?;
        let color = r.int_or_zero(30, 10, "field 4 (color)")?;
        let coordinates = if number == 15 {
            let c = [
                r.real(40, 13, "field 5 (x)")?,
                r.real(53, 13, "field 6 (y)")?,
                r.real(66, 13, "field 7 (z)")?,
            ];
            r.end(79)?;
            i += 1;
            c
        } else {
            r.end(40)?;
            let (c, next) = read_reals(
                ctx,
                lines,
                i + 1,
                &[25, 25, 25],
                3,
                &format!("node {label} record 2 (coordinates)"),
            )?;
            i = next;
            [c[0], c[1], c[2]]
        };
        nodes.push(Node {
            label,
            definition_cs,
            displacement_cs,
            color,
            coordinates,
        });
    }
    Ok(NodeSet {
        format: if number == 15 {
            NodeFormat::D15
        } else {
            NodeFormat::D2411
        },
        nodes,
    })
}

fn cs_kind(ctx: &Ctx, r: &Rec, code: i64) -> Result<CsKind, UffError> {
    CsKind::from_code(code).ok_or_else(|| {
        ctx.err(
            format!("{} field 2 (coordinate system type)", r.label),
            format!("unknown type code {code} (0 Cartesian, 1 cylindrical, 2 spherical)"),
        )
    })
}

fn parse_2420(ctx: &Ctx, lines: &[Line]) -> Result<CoordinateSystemSet, UffError> {
    let r1 = Rec::new(ctx, lines.first(), "record 1")?;
    let part_uid = r1.int(0, 10, "field 1 (part UID)")?;
    let part_name = lines.get(1).map(|l| free_text(l.bytes)).unwrap_or_default();
    if lines.len() < 2 {
        return Err(ctx.err("record 2 (part name)", "missing (dataset truncated)"));
    }
    let systems = read_systems(ctx, lines, 2, "record 3", |r3, i| {
        let (label, kind) = system_label_kind(ctx, r3, "field 1 (label)")?;
        let color = r3.int_or_zero(20, 10, "field 3 (color)")?;
        r3.end(40)?;
        let name = system_name(ctx, lines, i + 1, label, "record 4 (name)")?;
        let (m, next) = read_reals(
            ctx,
            lines,
            i + 2,
            &[25, 25, 25],
            12,
            &format!("system {label} records 5-8 (transformation matrix)"),
        )?;
        let definition = CsDefinition::Matrix {
            rows: [[m[0], m[1], m[2]], [m[3], m[4], m[5]], [m[6], m[7], m[8]]],
            origin: [m[9], m[10], m[11]],
        };
        Ok((system_of((label, kind, color), name, definition), next))
    })?;
    Ok(CoordinateSystemSet {
        dataset: 2420,
        part_uid: Some(part_uid),
        part_name,
        systems,
    })
}

fn parse_18(ctx: &Ctx, lines: &[Line]) -> Result<CoordinateSystemSet, UffError> {
    let systems = read_systems(ctx, lines, 0, "record 1", |r1, i| {
        let (label, kind) = system_label_kind(ctx, r1, "field 1 (coordinate system number)")?;
        let reference_cs = r1.int_or_zero(20, 10, "field 3 (reference system)")?;
        let color = r1.int_or_zero(30, 10, "field 4 (color)")?;
        let method = r1.int_or_zero(40, 10, "field 5 (method of definition)")?;
        r1.end(50)?;
        let name = system_name(ctx, lines, i + 1, label, "record 2 (name)")?;
        let (p, next) = read_reals(
            ctx,
            lines,
            i + 2,
            &[13, 13, 13, 13, 13, 13],
            9,
            &format!("system {label} record 3 (definition points)"),
        )?;
        let definition = CsDefinition::ThreePoints {
            reference_cs,
            method,
            origin: [p[0], p[1], p[2]],
            x_point: [p[3], p[4], p[5]],
            xz_point: [p[6], p[7], p[8]],
        };
        Ok((system_of((label, kind, color), name, definition), next))
    })?;
    Ok(CoordinateSystemSet {
        dataset: 18,
        part_uid: None,
        part_name: String::new(),
        systems,
    })
}

/// The coordinate systems of datasets 18 and 2420 from `lines[start..]`, blank lines
/// between them skipped: `system` reads one from its first record (`header`, read here
/// so that a truncated dataset is named by system) and the index of that record, and
/// returns it with the index of the line after it.
fn read_systems<'c, 'f>(
    ctx: &'c Ctx<'f>,
    lines: &[Line],
    start: usize,
    header: &str,
    system: impl Fn(&Rec<'c, 'f>, usize) -> Result<(CoordinateSystem, usize), UffError>,
) -> Result<Vec<CoordinateSystem>, UffError> {
    let mut systems = Vec::new();
    let mut i = start;
    while i < lines.len() {
        if trim_ascii(lines[i].bytes).is_empty() {
            i += 1;
            continue;
        }
        let n = systems.len() + 1;
        let r = Rec::new(ctx, lines.get(i), format!("system {n} {header}"))?;
        let (s, next) = system(&r, i)?;
        systems.push(s);
        i = next;
    }
    Ok(systems)
}

/// A coordinate system from its header fields (label, type, colour), name and definition.
fn system_of(
    (label, kind, color): (i64, CsKind, i64),
    name: String,
    definition: CsDefinition,
) -> CoordinateSystem {
    CoordinateSystem {
        label,
        kind,
        color,
        name,
        definition,
    }
}

/// Fields 1 and 2 of a coordinate system's first record: its label and its type.
fn system_label_kind(ctx: &Ctx, r: &Rec, label_field: &str) -> Result<(i64, CsKind), UffError> {
    let label = r.int(0, 10, label_field)?;
    let code = r.int(10, 10, "field 2 (type)")?;
    Ok((label, cs_kind(ctx, r, code)?))
}

/// A coordinate system's name line (free text), at `lines[at]`.
fn system_name(
    ctx: &Ctx,
    lines: &[Line],
    at: usize,
    label: i64,
    record: &str,
) -> Result<String, UffError> {
    let line = lines
        .get(at)
        .ok_or_else(|| ctx.err(format!("system {label} {record}"), "missing (truncated)"))?;
    Ok(free_text(line.bytes).trim().to_string())
}

fn parse_axis(ctx: &Ctx, line: Option<&Line>, which: &str) -> Result<AxisInfo, UffError> {
    let r = Rec::new(ctx, line, which)?;
    // The two labels are free text: a units label longer than its 20 columns is kept
    // whole (text fields never stop a read).
    let info = AxisInfo {
        data_type: r.int(0, 10, "field 1 (specific data type)")?,
        length_exp: r.int_or_zero(10, 5, "field 2 (length units exponent)")?,
        force_exp: r.int_or_zero(15, 5, "field 3 (force units exponent)")?,
        temperature_exp: r.int_or_zero(20, 5, "field 4 (temperature units exponent)")?,
        label: r.text(26, 20),
        units_label: r.text(47, usize::MAX / 2),
    };
    Ok(info)
}

/// Dataset 58 (function at nodal DOF): ID lines, records 6–11 (identification, data
/// characteristics, the four axes), then the data, ASCII (record 12) or binary (58b).
fn parse_58(
    ctx: &Ctx,
    lines: &[Line],
    binary: Option<(BinaryLayout, &[u8])>,
) -> Result<Function, UffError> {
    let id_lines = read_id_lines(ctx, lines)?;
    let ident = parse_58_identification(ctx, lines.get(5))?;
    let data = parse_58_data_characteristics(ctx, lines.get(6))?;
    let abscissa_axis = parse_axis(ctx, lines.get(7), "record 8 (abscissa)")?;
    let numerator = parse_axis(ctx, lines.get(8), "record 9 (ordinate numerator)")?;
    let denominator = parse_axis(ctx, lines.get(9), "record 10 (ordinate denominator)")?;
    let z_axis = parse_axis(ctx, lines.get(10), "record 11 (z axis)")?;

    let n = data.n;
    let n_numbers = n.checked_mul(data.numbers_per_point()).ok_or_else(|| {
        ctx.err(
            "record 7 field 2 (number of values)",
            format!("{n} is too large"),
        )
    })?;
    let (numbers, layout) = if let Some((layout, bytes)) = binary {
        let v = read_binary_values(ctx, lines.len(), &data, n_numbers, layout, bytes)?;
        (v, Some(layout))
    } else {
        (read_ascii_values(ctx, lines, &data, n_numbers)?, None)
    };
    let (abscissa, ordinate, samples) =
        if Function::is_sampled_time_history(ident.function_type, data.ordinate_type, data.even) {
            (Vec::new(), Vec::new(), numbers)
        } else {
            let (a, o) = data.points(&numbers);
            (a, o, Vec::new())
        };
    Ok(Function {
        id_lines,
        function_type: ident.function_type,
        function_id: ident.function_id,
        version: ident.version,
        load_case: ident.load_case,
        response_entity: ident.response_entity,
        response_node: ident.response_node,
        response_direction: ident.response_direction,
        reference_entity: ident.reference_entity,
        reference_node: ident.reference_node,
        reference_direction: ident.reference_direction,
        ordinate_type: data.ordinate_type,
        even: data.even,
        abscissa_min: data.abscissa_min,
        abscissa_increment: data.abscissa_increment,
        z_value: data.z_value,
        abscissa_axis,
        numerator,
        denominator,
        z_axis,
        binary: layout,
        abscissa,
        ordinate,
        samples,
        samples_set_aside: 0,
    })
}

/// Records 1–5 of dataset 58: the five free-text ID lines.
fn read_id_lines(ctx: &Ctx, lines: &[Line]) -> Result<[String; 5], UffError> {
    let mut id_lines: [String; 5] = Default::default();
    for (k, id) in id_lines.iter_mut().enumerate() {
        let l = lines.get(k).ok_or_else(|| {
            ctx.err(
                format!("record {} (ID line {})", k + 1, k + 1),
                "missing (dataset truncated)",
            )
        })?;
        *id = free_text(l.bytes);
    }
    Ok(id_lines)
}

/// Record 6 of dataset 58: what the function is and which response and reference
/// DOFs it relates.
struct FunctionIdentification {
    function_type: i64,
    function_id: i64,
    version: i64,
    load_case: i64,
    response_entity: String,
    response_node: i64,
    response_direction: i64,
    reference_entity: String,
    reference_node: i64,
    reference_direction: i64,
}

/// Reads record 6, refusing unknown function type and direction codes.
fn parse_58_identification(
    ctx: &Ctx,
    line: Option<&Line>,
) -> Result<FunctionIdentification, UffError> {
    let r6 = Rec::new(ctx, line, "record 6")?;
    let function_type = r6.int(0, 5, "field 1 (function type)")?;
    if !(0..=27).contains(&function_type) {
        return Err(ctx.err(
            format!("{} field 1 (function type)", r6.label),
            format!("unknown function type code {function_type} (expected 0..27; 4 = FRF)"),
        ));
    }
    let ident = FunctionIdentification {
        function_type,
        function_id: r6.int_or_zero(5, 10, "field 2 (function identification number)")?,
        version: r6.int_or_zero(15, 5, "field 3 (version number)")?,
        load_case: r6.int_or_zero(20, 10, "field 4 (load case)")?,
        response_entity: r6.text(31, 10),
        response_node: r6.int(41, 10, "field 6 (response node)")?,
        response_direction: r6.int(51, 4, "field 7 (response direction)")?,
        reference_entity: r6.text(56, 10),
        reference_node: r6.int_or_zero(66, 10, "field 9 (reference node)")?,
        reference_direction: r6.int_or_zero(76, 4, "field 10 (reference direction)")?,
    };
    r6.end(80)?;
    for (dir, name) in [
        (ident.response_direction, "field 7 (response direction)"),
        (ident.reference_direction, "field 10 (reference direction)"),
    ] {
        if !(-6..=6).contains(&dir) {
            return Err(ctx.err(
                format!("{} {name}", r6.label),
                format!("unknown direction code {dir} (expected -6..6)"),
            ));
        }
    }
    Ok(ident)
}

/// Record 7 of dataset 58: how the data are laid out.
struct DataCharacteristics {
    ordinate_type: OrdinateType,
    /// The ordinate data type code as written (for messages).
    code: i64,
    /// Number of points (at least one).
    n: usize,
    even: bool,
    abscissa_min: f64,
    abscissa_increment: f64,
    z_value: f64,
}

/// Reads record 7, refusing unknown codes and an empty function.
fn parse_58_data_characteristics(
    ctx: &Ctx,
    line: Option<&Line>,
) -> Result<DataCharacteristics, UffError> {
    let r7 = Rec::new(ctx, line, "record 7")?;
    let code = r7.int(0, 10, "field 1 (ordinate data type)")?;
    let ordinate_type = OrdinateType::from_code(code).ok_or_else(|| {
        ctx.err(
            format!("{} field 1 (ordinate data type)", r7.label),
            format!("unknown code {code} (2 real single, 4 real double, 5 complex single, 6 complex double)"),
        )
    })?;
    let n = r7.int(10, 10, "field 2 (number of values)")?;
    let spacing = r7.int(20, 10, "field 3 (abscissa spacing)")?;
    let abscissa_min = r7.real(30, 13, "field 4 (abscissa minimum)")?;
    let abscissa_increment = r7.real(43, 13, "field 5 (abscissa increment)")?;
    let z_value = if column(&r7.text, 56, 13).trim().is_empty() {
        0.0
    } else {
        r7.real(56, 13, "field 6 (z-axis value)")?
    };
    r7.end(69)?;
    let even = match spacing {
        0 => false,
        1 => true,
        s => {
            return Err(ctx.err(
                format!("{} field 3 (abscissa spacing)", r7.label),
                format!("unknown code {s} (0 uneven, 1 even)"),
            ))
        }
    };
    if n <= 0 {
        return Err(ctx.err(
            format!("{} field 2 (number of values)", r7.label),
            format!("{n} values: a function needs at least one"),
        ));
    }
    Ok(DataCharacteristics {
        ordinate_type,
        code,
        n: n as usize,
        even,
        abscissa_min,
        abscissa_increment,
        z_value,
    })
}

impl DataCharacteristics {
    /// Numbers stored per point: the abscissa unless evenly spaced, then the real
    /// part and, for complex data, the imaginary part.
    fn numbers_per_point(&self) -> usize {
        match (self.ordinate_type.is_complex(), self.even) {
            (false, true) => 1,
            (false, false) | (true, true) => 2,
            (true, false) => 3,
        }
    }

    /// Abscissa and ordinate of every point from the stored `numbers`.
    fn points(&self, numbers: &[f64]) -> (Vec<f64>, Vec<c64>) {
        let (n, per_point) = (self.n, self.numbers_per_point());
        let (x0, dx) = (self.abscissa_min, self.abscissa_increment);
        let mut abscissa = Vec::with_capacity(n);
        let mut ordinate = Vec::with_capacity(n);
        for k in 0..n {
            let p = &numbers[k * per_point..(k + 1) * per_point];
            let (x, y) = match (self.even, self.ordinate_type.is_complex()) {
                (true, false) => (x0 + k as f64 * dx, c64::new(p[0], 0.0)),
                (true, true) => (x0 + k as f64 * dx, c64::new(p[0], p[1])),
                (false, false) => (p[0], c64::new(p[1], 0.0)),
                (false, true) => (p[0], c64::new(p[1], p[2])),
            };
            abscissa.push(x);
            ordinate.push(y);
        }
        (abscissa, ordinate)
    }
}

/// The data of a 58b dataset: `n_numbers` single or double values in the announced
/// byte order, all finite. `n_ascii_lines` is the count of ASCII records read.
fn read_binary_values(
    ctx: &Ctx,
    n_ascii_lines: usize,
    data: &DataCharacteristics,
    n_numbers: usize,
    layout: BinaryLayout,
    bytes: &[u8],
) -> Result<Vec<f64>, UffError> {
    let n = data.n;
    if n_ascii_lines != 11 {
        return Err(ctx.err(
            "binary header field 5 (number of ASCII lines)",
            format!("dataset 58b has 11 ASCII records, the header announces {n_ascii_lines}"),
        ));
    }
    let size = if data.ordinate_type.is_double() { 8 } else { 4 };
    let expect = n_numbers.checked_mul(size);
    if expect != Some(bytes.len()) {
        return Err(ctx.err(
            "binary header field 6 (number of bytes)",
            format!(
                "{} bytes, but {n} values of ordinate type {} need {}",
                bytes.len(),
                data.code,
                expect.map_or("more than addressable".to_string(), |e| e.to_string())
            ),
        ));
    }
    let v: Vec<f64> = bytes
        .chunks_exact(size)
        .map(|c| match (size, layout.little_endian) {
            (8, true) => f64::from_le_bytes(c.try_into().expect("8 bytes")),
            (8, false) => f64::from_be_bytes(c.try_into().expect("8 bytes")),
            (_, true) => f32::from_le_bytes(c.try_into().expect("4 bytes")) as f64,
            (_, false) => f32::from_be_bytes(c.try_into().expect("4 bytes")) as f64,
        })
        .collect();
    if let Some(i) = v.iter().position(|x| !x.is_finite()) {
        return Err(ctx.err(
            "record 12 (binary data)",
            format!("value {} of {} is not finite ({})", i + 1, v.len(), v[i]),
        ));
    }
    Ok(v)
}

/// Record 12 of an ASCII dataset 58: `n_numbers` values in the fixed columns of the
/// ordinate type. When they do not read, values separated by blanks are accepted if
/// (and only if) their count matches record 7 exactly.
fn read_ascii_values(
    ctx: &Ctx,
    lines: &[Line],
    data: &DataCharacteristics,
    n_numbers: usize,
) -> Result<Vec<f64>, UffError> {
    let (n, code, even) = (data.n, data.code, data.even);
    let widths: &[usize] = match (
        data.ordinate_type.is_double(),
        data.ordinate_type.is_complex(),
        even,
    ) {
        (false, _, _) => &[13, 13, 13, 13, 13, 13],
        (true, _, true) => &[20, 20, 20, 20],
        (true, false, false) => &[13, 20, 13, 20],
        (true, true, false) => &[13, 20, 20],
    };
    let values = &lines[11.min(lines.len())..];
    let fixed = read_fixed_values(ctx, lines, widths, n, n_numbers);
    match fixed {
        Ok(v) => Ok(v),
        Err(fixed_err) => match blank_separated_values(values) {
            Some(v) if v.len() == n_numbers => Ok(v),
            Some(v) => {
                let extra = format!(
                    "read as blank-separated values instead there are {} numbers, but record 7 ({n} values, ordinate type {code}, {}) needs {n_numbers}: not guessing",
                    v.len(),
                    if even { "even spacing" } else { "uneven spacing" }
                );
                Err(match fixed_err {
                    UffError::Field { field, problem, .. } => {
                        ctx.err(field, format!("{problem}; {extra}"))
                    }
                    other => other,
                })
            }
            None => Err(fixed_err),
        },
    }
}
