//! Readable, exact mapping between JSON messages and flat CSV tables, guided by the
//! topic's JSON schema (stored beside the tables, so writer and reader use the same one).
//!
//! - Each message (a JSON object) is one row. Nested objects and fixed-size arrays become
//!   columns named by their path in words: `com_m.x`, `inertia_cm_kg_m2.xy` (3-vectors
//!   and 3×3 matrices), `residues.re` (`[re, im]` pairs), digits for other fixed arrays
//!   (`band_hz.0`, `stiffness.2.5`), field names for objects
//!   (`products_of_inertia_kg_m2.xy`).
//! - A field holding a list (an array whose length the schema does not fix) becomes its
//!   own *child table* `<table>_<field>`, one row per item; the parent row keeps the item
//!   count in the column `<field>_count`. Child rows start with the parent's *key*: the
//!   fewest leading text/integer columns of the parent that tell its rows apart
//!   (`excitation`, `setup`, `mode` for a mode), nothing when the parent has one row.
//!   Items that are not objects get an `index` column (0-based position in the list)
//!   and their value in `value` (or `re`/`im`, …).
//! - Cells: numbers in shortest round-trip form (floats bit-exact), `true`/`false`, text
//!   as it is. An empty cell is an absent optional value; where the schema does not say
//!   the field is text (free-form parameters), text that would read as something else is
//!   written as a JSON string literal, and the empty string is written `""`.
//!
//! [`to_tables`] and [`from_tables`] are inverse for any JSON that fits its schema.

use serde_json::{Map, Value};

/// One flat table.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    /// Table name: the topic's for the top table, `{parent}_{field}` (dots as `_`) for a child table.
    pub name: String,
    /// Parent table and the field (dotted path) whose items this table holds.
    pub parent: Option<(String, String)>,
    /// Key columns of this table: the parent's key columns first, then its own.
    pub key: Vec<String>,
    /// How many of `key` come from the parent.
    pub inherited: usize,
    /// Column names: key columns first, then the flattened fields.
    pub header: Vec<String>,
    /// Cells, one `Vec` per row in `header` order.
    pub rows: Vec<Vec<String>>,
}

/// Column of a non-object list item's position.
pub const INDEX: &str = "index";
/// Column of a scalar list item's value.
pub const VALUE: &str = "value";
/// Column numbering the rows (1-based) of a table whose columns do not tell them apart.
pub const ROW: &str = "row";
/// Suffix of the column holding a child table's item count.
pub const COUNT_SUFFIX: &str = "_count";

/// A node of a JSON schema as schemars writes them (`$defs` + `$ref`, `type` arrays or
/// `anyOf` with `null` for optional values). `true` (or anything unknown) is "any".
#[derive(Clone, Copy)]
pub struct Schema<'a> {
    root: &'a Value,
    node: &'a Value,
    /// The value is always there: the message itself, a property its object lists as
    /// `required` or that has a `default` (in an object that is always there and not
    /// nullable), a list's item, a fixed array's item when the array is always there.
    always_there: bool,
    /// The schema admits `null` (an `anyOf` with a `null` branch, or `null` among the types).
    nullable: bool,
}

static ANY: Value = Value::Bool(true);

impl<'a> Schema<'a> {
    /// The schema's root node (a `$ref` at the root is followed).
    pub fn new(root: &'a Value) -> Self {
        Schema {
            root,
            node: root,
            always_there: true,
            nullable: false,
        }
        .resolved()
    }
    fn at(&self, node: &'a Value, always_there: bool) -> Self {
        Schema {
            root: self.root,
            node,
            always_there,
            nullable: false,
        }
        .resolved()
    }
    fn resolved(self) -> Self {
        let mut n = self.node;
        let mut nullable = false;
        for _ in 0..64 {
            if let Some(r) = n.get("$ref").and_then(Value::as_str) {
                match r
                    .strip_prefix("#/$defs/")
                    .and_then(|name| self.root.get("$defs")?.get(name))
                {
                    Some(d) => {
                        n = d;
                        continue;
                    }
                    None => return Schema::any_in(self.root, self.always_there),
                }
            }
            if let Some(alts) = n
                .get("anyOf")
                .or_else(|| n.get("oneOf"))
                .and_then(Value::as_array)
            {
                let real: Vec<&Value> = alts
                    .iter()
                    .filter(|a| a.get("type").and_then(Value::as_str) != Some("null"))
                    .collect();
                nullable |= real.len() < alts.len();
                if real.len() == 1 {
                    n = real[0];
                    continue;
                }
                return Schema::any_in(self.root, self.always_there);
            }
            break;
        }
        let typed_null = match n.get("type") {
            Some(Value::String(t)) => t == "null",
            Some(Value::Array(a)) => a.iter().any(|t| t == "null"),
            _ => false,
        };
        Schema {
            root: self.root,
            node: n,
            always_there: self.always_there,
            nullable: nullable || typed_null,
        }
    }
    fn any_in(root: &'a Value, always_there: bool) -> Self {
        Schema {
            root,
            node: &ANY,
            always_there,
            nullable: true,
        }
    }
    fn types(&self) -> Vec<&'a str> {
        match self.node.get("type") {
            Some(Value::String(s)) => vec![s.as_str()],
            Some(Value::Array(a)) => a.iter().filter_map(Value::as_str).collect(),
            _ => Vec::new(),
        }
    }
    /// The schema says this is text (and nothing else but null).
    fn is_text(&self) -> bool {
        let t = self.types();
        t.contains(&"string") && t.iter().all(|x| *x == "string" || *x == "null")
    }
    fn is_array(&self) -> bool {
        self.types() == ["array"]
    }
    /// An array or null (`Option<[T; N]>`, `Option<Vec<T>>`): written as a fixed array,
    /// digits for positions, so its columns index an array when read back.
    fn is_array_or_null(&self) -> bool {
        let t = self.types();
        t.contains(&"array") && t.iter().all(|x| *x == "array" || *x == "null")
    }
    fn property(&self, name: &str) -> Schema<'a> {
        let required = self
            .node
            .get("required")
            .and_then(Value::as_array)
            .is_some_and(|r| r.iter().any(|f| f == name));
        match self.node.get("properties").and_then(|p| p.get(name)) {
            // A field with a default is written whatever its value (schemars leaves the
            // default out when `skip_serializing_if` would skip it). Inside an optional
            // or nullable object nothing is always there.
            Some(n) => self.at(
                n,
                (required || n.get("default").is_some()) && self.always_there && !self.nullable,
            ),
            None => Schema::any_in(self.root, false),
        }
    }
    fn items(&self) -> Schema<'a> {
        match self.node.get("items") {
            // A list's items are rows of their own (there when the row is); a fixed
            // array's are there when the array is.
            Some(n) if n.is_object() => self.at(n, self.is_list() || self.always_there),
            _ => Schema::any_in(self.root, self.is_list() || self.always_there),
        }
    }
    /// An empty cell of this field is the empty string: text that is always there and
    /// cannot be null (so the empty cell cannot mean "absent" instead).
    fn empty_cell_is_empty_text(&self) -> bool {
        self.is_text() && self.always_there && !self.nullable
    }
    /// Length of an array the schema fixes (`minItems == maxItems`).
    fn fixed_len(&self) -> Option<usize> {
        if !self.is_array() {
            return None;
        }
        let min = self.node.get("minItems")?.as_u64()?;
        let max = self.node.get("maxItems")?.as_u64()?;
        (min == max).then_some(min as usize)
    }
    /// A list: an array whose length the schema does not fix.
    fn is_list(&self) -> bool {
        self.is_array() && self.fixed_len().is_none()
    }
    fn describes_re_im(&self) -> bool {
        self.node
            .get("description")
            .and_then(Value::as_str)
            .is_some_and(|d| d.contains("[re, im]"))
    }
}

/// Names of the positions of a fixed array: x/y/z for 3-vectors, re/im for pairs the
/// field documents as `[re, im]`, digits otherwise.
fn position_names(len: usize, re_im: bool) -> Option<&'static [&'static str]> {
    match (len, re_im) {
        (3, _) => Some(&["x", "y", "z"]),
        (2, true) => Some(&["re", "im"]),
        _ => None,
    }
}

const MATRIX3: [&str; 9] = ["xx", "xy", "xz", "yx", "yy", "yz", "zx", "zy", "zz"];

/// Text of one scalar cell, given what the schema says the value is.
///
/// The empty string is an empty cell where the schema says the text is always there and
/// cannot be null ([`Schema::empty_cell_is_empty_text`]: a set-up's description, an id);
/// only where an empty cell means "absent" (optional or nullable text) is it written `""`.
fn cell_text(v: &Value, s: Schema) -> String {
    match v {
        Value::String(t) if s.empty_cell_is_empty_text() => t.clone(),
        Value::String(t) if s.is_text() => {
            if t.is_empty() {
                "\"\"".into()
            } else {
                t.clone()
            }
        }
        Value::String(t) => {
            if t.is_empty() || t.trim() != t || serde_json::from_str::<Value>(t).is_ok() {
                serde_json::to_string(t).expect("string serialises")
            } else {
                t.clone()
            }
        }
        other => other.to_string(),
    }
}

/// Value of one cell (`None` for an empty cell, unless it is text that is always there).
fn cell_value(text: &str, s: Schema) -> Option<Value> {
    if text.is_empty() {
        return s
            .empty_cell_is_empty_text()
            .then(|| Value::String(String::new()));
    }
    if s.is_text() {
        return Some(Value::String(
            if text == "\"\"" && !s.empty_cell_is_empty_text() {
                String::new()
            } else {
                text.to_string()
            },
        ));
    }
    Some(serde_json::from_str::<Value>(text).unwrap_or_else(|_| Value::String(text.to_string())))
}

/// A row being built: (column, cell) in field order, and the lists found on the way.
struct RowOut<'v, 's> {
    cells: Vec<(String, String)>,
    /// (field path, items, item schema, the list's own schema)
    lists: Vec<(String, &'v [Value], Schema<'s>, Schema<'s>)>,
}

fn join(path: &str, seg: &str) -> String {
    if path.is_empty() {
        seg.to_string()
    } else {
        format!("{path}.{seg}")
    }
}

/// Flattens `v` (schema `s`) at `path` into the row; lists at field level go to `lists`.
fn flatten_value<'v, 's>(
    path: &str,
    v: &'v Value,
    s: Schema<'s>,
    re_im: bool,
    in_list_item: bool,
    out: &mut RowOut<'v, 's>,
) {
    match v {
        Value::Null => out.cells.push((path.into(), String::new())),
        Value::Object(o) if !o.is_empty() => {
            for (k, x) in o {
                let fs = s.property(k);
                flatten_value(&join(path, k), x, fs, fs.describes_re_im(), false, out);
            }
        }
        Value::Array(a) if s.is_list() && !in_list_item => {
            out.cells
                .push((format!("{path}{COUNT_SUFFIX}"), a.len().to_string()));
            out.lists.push((path.to_string(), a, s.items(), s));
        }
        Value::Array(a) if !a.is_empty() => {
            let items = s.items();
            let names = s.fixed_len().and_then(|n| position_names(n, re_im));
            // A 3×3 matrix: one column per entry, `xy`.
            if names.is_some()
                && a.len() == 3
                && items.fixed_len() == Some(3)
                && a.iter().all(|r| r.as_array().is_some_and(|r| r.len() == 3))
            {
                for (i, row) in a.iter().enumerate() {
                    for (j, x) in row.as_array().unwrap().iter().enumerate() {
                        flatten_value(
                            &join(path, MATRIX3[3 * i + j]),
                            x,
                            items.items(),
                            false,
                            true,
                            out,
                        );
                    }
                }
                return;
            }
            for (i, x) in a.iter().enumerate() {
                let seg = match names {
                    Some(n) if n.len() == a.len() => n[i].to_string(),
                    _ => i.to_string(),
                };
                flatten_value(&join(path, &seg), x, items, re_im, true, out);
            }
        }
        Value::Array(_) => out.cells.push((path.into(), "[]".into())),
        Value::Object(_) => out.cells.push((path.into(), "{}".into())),
        scalar => out.cells.push((path.into(), cell_text(scalar, s))),
    }
}

/// Flattens a topic's messages (schema `schema`) into its table and child tables,
/// appended to `out` parent first.
pub fn to_tables(name: &str, messages: &[Value], schema: &Value, out: &mut Vec<Table>) {
    let s = Schema::new(schema);
    let rows: Vec<(Vec<String>, &Value)> = messages.iter().map(|m| (Vec::new(), m)).collect();
    table_of(name, None, &[], rows, s, (false, false), out);
}

/// Builds one table from its rows (each with its inherited key values) and recurses
/// into its lists.
fn table_of(
    name: &str,
    parent: Option<(String, String)>,
    inherited: &[String],
    rows: Vec<(Vec<String>, &Value)>,
    item: Schema,
    (indexed, re_im): (bool, bool),
    out: &mut Vec<Table>,
) {
    let built = flatten_rows(&rows, item, indexed, re_im);
    // Columns: inherited key, then every column in first-appearance order.
    let mut own_header: Vec<String> = Vec::new();
    for r in &built {
        for (k, _) in &r.cells {
            if !own_header.contains(k) {
                own_header.push(k.clone());
            }
        }
    }
    // The inherited key keeps its names unless an own column has the name.
    let key_in: Vec<String> = inherited
        .iter()
        .map(|k| {
            let mut k = k.clone();
            while own_header.contains(&k) {
                k = format!("parent_{k}");
            }
            k
        })
        .collect();
    let mut header = key_in.clone();
    header.extend(own_header.iter().cloned());
    let text_rows: Vec<Vec<String>> = built
        .iter()
        .zip(&rows)
        .map(|(r, (kv, _))| {
            let mut row = kv.clone();
            row.resize(key_in.len(), String::new());
            let mut own = vec![String::new(); own_header.len()];
            for (k, t) in &r.cells {
                let j = own_header.iter().position(|h| h == k).unwrap();
                own[j] = t.clone();
            }
            row.extend(own);
            row
        })
        .collect();
    let mut own_key = own_key_columns(&text_rows, &own_header, key_in.len());
    let mut text_rows = text_rows;
    if text_rows.len() > 1 && own_key.is_empty() {
        // No columns tell the rows apart: number them (1-based) in a column `row`.
        header.insert(key_in.len(), ROW.into());
        for (i, r) in text_rows.iter_mut().enumerate() {
            r.insert(key_in.len(), (i + 1).to_string());
        }
        own_key.push(key_in.len());
    }
    let mut key = key_in.clone();
    key.extend(own_key.iter().map(|&c| header[c].clone()));
    let pos = out.len();
    out.push(Table {
        name: name.into(),
        parent,
        key,
        inherited: key_in.len(),
        header: header.clone(),
        rows: text_rows.clone(),
    });
    let fields = list_fields(&built);
    let key_cols: Vec<usize> = out[pos]
        .key
        .iter()
        .map(|k| header.iter().position(|h| h == k).unwrap())
        .collect();
    for (field, is, ls) in fields {
        let mut items: Vec<(Vec<String>, &Value)> = Vec::new();
        for (r, tr) in built.iter().zip(&text_rows) {
            let kv: Vec<String> = key_cols.iter().map(|&c| tr[c].clone()).collect();
            for (f, list, _, _) in &r.lists {
                if *f == field {
                    items.extend(list.iter().map(|x| (kv.clone(), x)));
                }
            }
        }
        let item_is_object = items.iter().all(|(_, v)| v.is_object()) && !items.is_empty()
            || (items.is_empty() && is.types() == ["object"]);
        let child_key: Vec<String> = out[pos].key.clone();
        table_of(
            &format!("{name}_{}", field.replace('.', "_")),
            Some((name.into(), field)),
            &child_key,
            items,
            is,
            (!item_is_object, ls.describes_re_im()),
            out,
        );
    }
}

/// Each row flattened into its cells and lists; `indexed` rows (list items that are not
/// objects) get their position within their parent's list.
fn flatten_rows<'v, 's>(
    rows: &[(Vec<String>, &'v Value)],
    item: Schema<'s>,
    indexed: bool,
    re_im: bool,
) -> Vec<RowOut<'v, 's>> {
    let mut built: Vec<RowOut> = Vec::new();
    // Position within the parent's list: items come grouped by parent (unique keys).
    let mut position = 0usize;
    for (i, (kv, v)) in rows.iter().enumerate() {
        let mut r = RowOut {
            cells: Vec::new(),
            lists: Vec::new(),
        };
        if i > 0 && rows[i - 1].0 == *kv {
            position += 1;
        } else {
            position = 0;
        }
        if indexed {
            r.cells.push((INDEX.into(), position.to_string()));
        }
        match v {
            Value::Object(o) if !o.is_empty() => flatten_value("", v, item, false, false, &mut r),
            _ if indexed => {
                let named = item.fixed_len().and_then(|n| position_names(n, re_im));
                if named.is_some() && v.is_array() {
                    flatten_value("", v, item, re_im, true, &mut r)
                } else {
                    flatten_value(VALUE, v, item, re_im, true, &mut r)
                }
            }
            _ => flatten_value(VALUE, v, item, false, true, &mut r),
        }
        built.push(r);
    }
    built
}

/// Own key: the fewest leading text/integer columns that tell the rows apart (with the
/// `n_inherited` inherited key columns); none for a single row or when no prefix does.
fn own_key_columns(
    text_rows: &[Vec<String>],
    own_header: &[String],
    n_inherited: usize,
) -> Vec<usize> {
    if text_rows.len() <= 1 {
        return Vec::new();
    }
    let candidates: Vec<usize> = own_header
        .iter()
        .enumerate()
        .filter(|(j, h)| {
            !h.ends_with(COUNT_SUFFIX) && text_rows.iter().all(|r| is_key_cell(&r[n_inherited + j]))
        })
        .map(|(j, _)| n_inherited + j)
        .collect();
    for n in 1..=candidates.len() {
        let cols = &candidates[..n];
        let mut seen = std::collections::HashSet::new();
        if text_rows.iter().all(|r| {
            let mut k: Vec<&str> = r[..n_inherited].iter().map(String::as_str).collect();
            k.extend(cols.iter().map(|&c| r[c].as_str()));
            seen.insert(k)
        }) {
            return cols.to_vec();
        }
    }
    Vec::new()
}

/// The list fields of the rows (each a child table), in first-appearance order, with the
/// schemas of the list and of its items.
fn list_fields<'s>(built: &[RowOut<'_, 's>]) -> Vec<(String, Schema<'s>, Schema<'s>)> {
    let mut fields: Vec<(String, Schema, Schema)> = Vec::new();
    for r in built {
        for (f, _, is, ls) in &r.lists {
            if !fields.iter().any(|(g, _, _)| g == f) {
                fields.push((f.clone(), *is, *ls));
            }
        }
    }
    fields
}

/// A cell that can serve as a key: non-empty text or an integer.
fn is_key_cell(t: &str) -> bool {
    !t.is_empty()
        && (t.parse::<i64>().is_ok() || t.parse::<f64>().is_err())
        && t != "true"
        && t != "false"
}

/// Resolves a column path to JSON path segments (indices for words under arrays).
fn segments(path: &str, mut s: Schema, mut re_im: bool) -> Result<Vec<Seg>, String> {
    let mut out = Vec::new();
    for part in path.split('.') {
        if s.is_array_or_null() {
            let len = s.fixed_len();
            let names = len.and_then(|n| position_names(n, re_im));
            if let Some(k) = MATRIX3.iter().position(|m| *m == part) {
                if s.items().is_array() && len == Some(3) {
                    out.push(Seg::Index(k / 3));
                    out.push(Seg::Index(k % 3));
                    s = s.items().items();
                    continue;
                }
            }
            let i = match names.and_then(|n| n.iter().position(|x| *x == part)) {
                Some(i) => i,
                None => part
                    .parse::<usize>()
                    .map_err(|_| format!("column segment '{part}' does not index an array"))?,
            };
            out.push(Seg::Index(i));
            s = s.items();
        } else if let (Ok(i), true) = (part.parse::<usize>(), s.types().is_empty()) {
            // Free-form (schema-less) value: digits index arrays, as written.
            out.push(Seg::Index(i));
        } else {
            out.push(Seg::Key(part.to_string()));
            s = s.property(part);
            re_im = s.describes_re_im();
        }
    }
    Ok(out)
}

enum Seg {
    Key(String),
    Index(usize),
}

/// Largest gap a column's position may leave in a list (a huge position in a header
/// must not allocate a huge list).
const MAX_INDEX_GAP: usize = 64;

fn set_path(root: &mut Value, path: &[Seg], v: Value) -> Result<(), String> {
    let Some((first, rest)) = path.split_first() else {
        *root = v;
        return Ok(());
    };
    match first {
        Seg::Index(i) => {
            if root.is_null() {
                *root = Value::Array(Vec::new());
            }
            let a = root
                .as_array_mut()
                .ok_or_else(|| format!("'{i}' indexes a non-array"))?;
            if *i > a.len() + MAX_INDEX_GAP {
                return Err(format!(
                    "position {i} leaves a gap after {} items (positions come in order)",
                    a.len()
                ));
            }
            if a.len() <= *i {
                a.resize(i + 1, Value::Null);
            }
            set_path(&mut a[*i], rest, v)
        }
        Seg::Key(k) => {
            if root.is_null() {
                *root = Value::Object(Map::new());
            }
            let o = root
                .as_object_mut()
                .ok_or_else(|| format!("'{k}' names a field of a non-object"))?;
            set_path(o.entry(k.clone()).or_insert(Value::Null), rest, v)
        }
    }
}

/// The schema of a list field at a dotted path below `s`.
fn schema_at<'a>(mut s: Schema<'a>, path: &str) -> Schema<'a> {
    for part in path.split('.') {
        s = if s.is_array() {
            s.items()
        } else {
            s.property(part)
        };
    }
    s
}

/// Rebuilds the messages of top-level table `name` (with its child tables from `all`,
/// whose parents come before them). Errors carry the table name and 1-based data row.
pub fn from_tables(name: &str, all: &[Table], schema: &Value) -> Result<Vec<Value>, String> {
    Ok(read_table(name, all, Schema::new(schema), (false, false))?.values)
}

/// One table read back: values, each row's key tuple and (for list items) its index.
struct Read {
    values: Vec<Value>,
    keys: Vec<Vec<String>>,
    index: Vec<Option<usize>>,
}

/// Reads table `name` (items of schema `item`) and its children.
fn read_table(
    name: &str,
    all: &[Table],
    item: Schema,
    (indexed, re_im): (bool, bool),
) -> Result<Read, String> {
    let t = all
        .iter()
        .find(|t| t.name == name)
        .ok_or_else(|| format!("table {name} missing"))?;
    let col = |k: &str| {
        t.header
            .iter()
            .position(|h| h == k)
            .ok_or_else(|| format!("{name}: key column '{k}' missing"))
    };
    let key_cols: Vec<usize> = t.key.iter().map(|k| col(k)).collect::<Result<_, _>>()?;
    let children: Vec<&Table> = all
        .iter()
        .filter(|c| c.parent.as_ref().is_some_and(|(p, _)| p == name))
        .collect();
    let reader = TableReader {
        name,
        t,
        item,
        indexed,
        re_im,
        inherited: key_cols[..t.inherited.min(key_cols.len())].to_vec(),
        count_cols: children
            .iter()
            .map(|c| format!("{}{COUNT_SUFFIX}", c.parent.as_ref().unwrap().1))
            .collect(),
        children: &children,
    };
    let mut out = Read {
        values: Vec::with_capacity(t.rows.len()),
        keys: Vec::with_capacity(t.rows.len()),
        index: Vec::with_capacity(t.rows.len()),
    };
    for (r, row) in t.rows.iter().enumerate() {
        let (v, index) = reader.row_value(r, row)?;
        out.keys
            .push(key_cols.iter().map(|&c| row[c].clone()).collect());
        out.index.push(index);
        out.values.push(v);
    }
    for child in &children {
        reader.attach_child(child, all, &mut out)?;
    }
    Ok(out)
}

/// One table being read: where its inherited key, its children's counts and its items'
/// schema are.
struct TableReader<'a, 's> {
    name: &'a str,
    t: &'a Table,
    item: Schema<'s>,
    indexed: bool,
    re_im: bool,
    /// Header positions of the inherited key (the parent's, not this row's own value).
    inherited: Vec<usize>,
    children: &'a [&'a Table],
    /// The item-count column of each child.
    count_cols: Vec<String>,
}

impl TableReader<'_, '_> {
    /// Row `r`'s value (an object, or a list item) and, for a list item, its index.
    fn row_value(&self, r: usize, row: &[String]) -> Result<(Value, Option<usize>), String> {
        let (name, t, item) = (self.name, self.t, self.item);
        let at = |e: String| format!("{name}: row {}: {e}", r + 1);
        if row.len() != t.header.len() {
            return Err(at(format!(
                "{} cells for {} columns",
                row.len(),
                t.header.len()
            )));
        }
        let mut v = Value::Null;
        let mut index = None;
        for (j, (h, text)) in t.header.iter().zip(row).enumerate() {
            if self.inherited.contains(&j) {
                continue;
            }
            if self.indexed && h == INDEX {
                index = Some(
                    text.parse::<usize>()
                        .map_err(|_| at(format!("{INDEX} '{text}' is not a position")))?,
                );
                continue;
            }
            if let Some(c) = self.count_cols.iter().position(|c| c == h) {
                // Keeps the field's place among the fields; the child table fills it.
                if !text.is_empty() {
                    let field = &self.children[c].parent.as_ref().unwrap().1;
                    let segs =
                        segments(field, item, false).map_err(|e| at(format!("column {h}: {e}")))?;
                    set_path(&mut v, &segs, Value::Array(Vec::new()))
                        .map_err(|e| at(format!("column {h}: {e}")))?;
                }
                continue;
            }
            if !self.indexed && h == ROW && t.key[self.inherited.len()..].iter().any(|k| k == ROW) {
                continue;
            }
            // A list item's `value` column stands for the item itself.
            let path = match h.strip_prefix(VALUE) {
                Some("") if self.indexed || !item.types().contains(&"object") => "",
                Some(rest) if self.indexed && rest.starts_with('.') => &rest[1..],
                _ => h.as_str(),
            };
            let cs = if path.is_empty() {
                item
            } else {
                cell_schema(item, path)
            };
            let Some(x) = cell_value(text, cs) else {
                continue;
            };
            let segs = if path.is_empty() {
                Vec::new()
            } else {
                segments(path, item, self.re_im).map_err(|e| at(format!("column {h}: {e}")))?
            };
            set_path(&mut v, &segs, x).map_err(|e| at(format!("column {h}: {e}")))?;
        }
        if v.is_null() && !self.indexed {
            v = Value::Object(Map::new());
        }
        Ok((v, index))
    }

    /// Reads child table `child` and puts its items into the lists of their parent rows
    /// (matched by the inherited key, in order), then checks each parent's item count.
    fn attach_child(&self, child: &Table, all: &[Table], out: &mut Read) -> Result<(), String> {
        let (name, item) = (self.name, self.item);
        let field = &child.parent.as_ref().unwrap().1;
        let list = schema_at(item, field);
        let indexed_child =
            child.header.iter().any(|h| h == INDEX) && list.items().types() != ["object"];
        let kids = read_table(
            &child.name,
            all,
            list.items(),
            (indexed_child, list.describes_re_im()),
        )?;
        let n_in = child.inherited;
        let segs = segments(field, item, false).map_err(|e| format!("{}: {e}", child.name))?;
        let mut next = 0usize;
        for (r, kid) in kids.values.into_iter().enumerate() {
            let kk = &kids.keys[r];
            let want = &kk[..n_in.min(kk.len())];
            // Items come in parent order: advance to the parent row with this key.
            while next < out.keys.len() && out.keys[next] != want {
                next += 1;
            }
            let at = |e: String| format!("{}: row {}: {e}", child.name, r + 1);
            let parent = out.values.get_mut(next).ok_or_else(|| {
                at(format!(
                    "no row of {name} (after the previous item's) has the key '{}'",
                    want.join(", ")
                ))
            })?;
            let slot = get_path_mut(parent, &segs)
                .and_then(Value::as_array_mut)
                .ok_or_else(|| {
                    at(format!(
                        "the parent row's {field}{COUNT_SUFFIX} is empty or not a list"
                    ))
                })?;
            if let Some(i) = kids.index[r] {
                if i != slot.len() {
                    return Err(at(format!(
                        "{INDEX} {i}, expected {} (items in order)",
                        slot.len()
                    )));
                }
            }
            slot.push(kid);
        }
        self.check_counts(child, field, &segs, &out.values)
    }

    /// Each parent's count must equal the items found for it.
    fn check_counts(
        &self,
        child: &Table,
        field: &str,
        segs: &[Seg],
        values: &[Value],
    ) -> Result<(), String> {
        let (name, t) = (self.name, self.t);
        let Some(ci) = t
            .header
            .iter()
            .position(|h| *h == format!("{field}{COUNT_SUFFIX}"))
        else {
            return Ok(());
        };
        for (r, (row, v)) in t.rows.iter().zip(values).enumerate() {
            if row[ci].is_empty() {
                continue;
            }
            let n: usize = row[ci].parse().map_err(|_| {
                format!(
                    "{name}: row {}: {field}{COUNT_SUFFIX} '{}' is not a count",
                    r + 1,
                    row[ci]
                )
            })?;
            let got = get_path(v, segs)
                .and_then(Value::as_array)
                .map_or(0, Vec::len);
            if got != n {
                return Err(format!(
                    "{name}: row {}: {field}{COUNT_SUFFIX} is {n} but {} has {got} rows for it",
                    r + 1,
                    child.name
                ));
            }
        }
        Ok(())
    }
}

fn cell_schema<'a>(item: Schema<'a>, path: &str) -> Schema<'a> {
    let mut s = item;
    for part in path.split('.') {
        s = if s.is_array() {
            if MATRIX3.contains(&part) && s.items().is_array() {
                s.items().items()
            } else {
                s.items()
            }
        } else {
            s.property(part)
        };
    }
    s
}

fn get_path_mut<'v>(v: &'v mut Value, segs: &[Seg]) -> Option<&'v mut Value> {
    let mut v = v;
    for s in segs {
        v = match s {
            Seg::Key(k) => v.as_object_mut()?.get_mut(k)?,
            Seg::Index(i) => v.as_array_mut()?.get_mut(*i)?,
        };
    }
    Some(v)
}

fn get_path<'v>(v: &'v Value, segs: &[Seg]) -> Option<&'v Value> {
    let mut v = v;
    for s in segs {
        v = match s {
            Seg::Key(k) => v.as_object()?.get(k)?,
            Seg::Index(i) => v.as_array()?.get(*i)?,
        };
    }
    Some(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn schema() -> Value {
        json!({
            "type": "object",
            "properties": {
                "id": {"type": "string"},
                "note": {"type": ["string", "null"]},
                "com_m": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3},
                "j": {"type": "array", "items": {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}, "minItems": 3, "maxItems": 3},
                "band": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2},
                "warnings": {"type": "array", "items": {"type": "string"}},
                "modes": {"type": "array", "items": {"$ref": "#/$defs/Mode"}},
                "free": true
            },
            "$defs": {
                "Mode": {
                    "type": "object",
                    "properties": {
                        "excitation": {"type": "string"},
                        "mode": {"type": "integer"},
                        "residues": {"description": "per channel, `[re, im]`", "type": "array",
                                     "items": {"type": "array", "items": {"type": "number"}, "minItems": 2, "maxItems": 2}},
                        "fit": {"type": "array", "items": {"type": "number"}}
                    }
                }
            }
        })
    }

    #[test]
    fn readable_tables_round_trip_exactly() {
        let msgs = vec![
            json!({"id": "101", "note": null, "com_m": [0.1, -0.0, 2.5e-300], "j": [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]],
                   "band": [0.5, 8.0], "warnings": ["true", "a, b"], "free": {"k": "42", "v": [1, 2]},
                   "modes": [{"excitation": "201-x", "mode": 1, "residues": [[0.1, -0.2], [3e-9, 4.0]], "fit": []},
                             {"excitation": "201-x", "mode": 2, "residues": [], "fit": [1e-30]}]}),
            json!({"id": "", "note": "", "com_m": [1.0, 2.0, 3.0], "j": [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
                   "band": [0.0, 1.0], "warnings": [], "free": {"k": "x"},
                   "modes": [{"excitation": "202y", "mode": 1, "residues": [[1.0, 1.0]], "fit": [0.5, 0.25]}]}),
        ];
        let s = schema();
        let mut tables = Vec::new();
        to_tables("topic", &msgs, &s, &mut tables);
        let names: Vec<&str> = tables.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(
            names,
            [
                "topic",
                "topic_warnings",
                "topic_modes",
                "topic_modes_residues",
                "topic_modes_fit"
            ]
        );
        let top = &tables[0];
        // Plain ids, words for positions, counts for lists.
        assert_eq!(top.rows[0][0], "101");
        for h in [
            "com_m.x",
            "j.xy",
            "band.0",
            "warnings_count",
            "modes_count",
            "free.k",
        ] {
            assert!(top.header.iter().any(|x| x == h), "{h} in {:?}", top.header);
        }
        assert_eq!(top.key, ["id"]);
        let modes = &tables[2];
        assert_eq!(modes.key, ["id", "excitation", "mode"]);
        assert_eq!(modes.inherited, 1);
        let res = &tables[3];
        assert_eq!(
            res.header,
            ["id", "excitation", "mode", "index", "re", "im"]
        );
        assert_eq!(res.rows[0], ["101", "201-x", "1", "0", "0.1", "-0.2"]);
        let back = from_tables("topic", &tables, &s).unwrap();
        let mut expect = msgs.clone();
        expect[0].as_object_mut().unwrap().remove("note");
        assert_eq!(back, expect);
        assert_eq!(
            back[0]["com_m"][2].as_f64().unwrap().to_bits(),
            2.5e-300f64.to_bits()
        );
        // Field order survives (the MCAP bytes depend on it).
        let keys = |v: &Value| v.as_object().unwrap().keys().cloned().collect::<Vec<_>>();
        assert_eq!(keys(&back[1]), keys(&expect[1]));
        // A list item out of order is an error naming the table and row.
        let mut bad = tables.clone();
        bad[3].rows.swap(0, 1);
        let e = from_tables("topic", &bad, &s).unwrap_err();
        assert!(e.contains("topic_modes_residues: row 1"), "{e}");
        // So is a count that disagrees with the rows.
        let mut bad = tables.clone();
        let c = bad[0]
            .header
            .iter()
            .position(|h| h == "warnings_count")
            .unwrap();
        bad[0].rows[0][c] = "3".into();
        let e = from_tables("topic", &bad, &s).unwrap_err();
        assert!(e.contains("warnings_count is 3"), "{e}");
    }

    /// An optional fixed array (`Option<[[f64; 6]; 6]>`, schemars' `"type": ["array",
    /// "null"]`) is written with digit positions and reads back as the array, not as an
    /// object keyed by digits; absent, it stays absent.
    #[test]
    fn optional_fixed_arrays_round_trip() {
        let row6 =
            json!({"type": "array", "items": {"type": "number"}, "minItems": 6, "maxItems": 6});
        let s = json!({"type": "object", "properties": {
            "id": {"type": "string"},
            "k": {"type": ["array", "null"], "items": row6, "minItems": 6, "maxItems": 6}}});
        let k: Vec<Vec<f64>> = (0..6)
            .map(|i| (0..6).map(|j| (6 * i + j) as f64 - 0.5).collect())
            .collect();
        let msgs = vec![json!({"id": "a", "k": k}), json!({"id": "b", "k": null})];
        let mut tables = Vec::new();
        to_tables("t", &msgs, &s, &mut tables);
        assert!(
            tables[0].header.iter().any(|h| h == "k.5.4"),
            "{:?}",
            tables[0].header
        );
        let back = from_tables("t", &tables, &s).unwrap();
        assert_eq!(back[0], msgs[0]);
        assert_eq!(back[1], json!({"id": "b"}));
    }

    /// The empty-text rule: an empty cell is the empty string where the text is always
    /// there and cannot be null, and "absent" everywhere else (where `""` stands for the
    /// empty string, so both round-trip).
    #[test]
    fn empty_text_cells_follow_whether_the_field_is_always_there() {
        let s = json!({
            "type": "object",
            "required": ["id", "label", "names", "part"],
            "properties": {
                "id": {"type": "string"},
                "label": {"type": "string"},
                "advice": {"type": "string", "default": ""},
                "optional": {"type": "string"},
                "nullable": {"type": ["string", "null"]},
                "names": {"type": "array", "items": {"type": "string"}},
                "part": {"anyOf": [{"$ref": "#/$defs/Part"}, {"type": "null"}]}
            },
            "$defs": {"Part": {"type": "object", "required": ["name"],
                               "properties": {"name": {"type": "string"}}}}
        });
        let msgs = vec![
            json!({"id": "a", "label": "", "advice": "", "optional": "", "nullable": "", "names": ["", "x"],
                   "part": {"name": ""}}),
            json!({"id": "b", "label": "\"\"", "advice": "x", "nullable": null, "names": [], "part": null}),
        ];
        let mut tables = Vec::new();
        to_tables("t", &msgs, &s, &mut tables);
        let cell = |r: usize, h: &str| {
            let c = tables[0].header.iter().position(|x| x == h).unwrap();
            tables[0].rows[r][c].clone()
        };
        assert_eq!(cell(0, "label"), "");
        assert_eq!(cell(0, "advice"), "");
        assert_eq!(cell(0, "optional"), "\"\"");
        assert_eq!(cell(0, "nullable"), "\"\"");
        assert_eq!(cell(1, "nullable"), "");
        // Inside a nullable object a required field is not always there.
        assert_eq!(cell(0, "part.name"), "\"\"");
        assert_eq!(cell(1, "part.name"), "");
        // Text that is two quote marks stays itself.
        assert_eq!(cell(1, "label"), "\"\"");
        assert_eq!(tables[1].rows[0], ["a", "0", ""]);
        let back = from_tables("t", &tables, &s).unwrap();
        let mut expect = msgs.clone();
        expect[1].as_object_mut().unwrap().remove("nullable");
        expect[1].as_object_mut().unwrap().remove("part");
        assert_eq!(back, expect);
    }

    #[test]
    fn rows_nothing_tells_apart_are_numbered() {
        let s = json!({"type": "object", "properties": {"tool": {"type": "string"},
            "args": {"type": "array", "items": {"type": "string"}}}});
        let msgs = vec![
            json!({"tool": "a", "args": ["-x"]}),
            json!({"tool": "a", "args": ["-y", "1"]}),
        ];
        let mut tables = Vec::new();
        to_tables("p", &msgs, &s, &mut tables);
        assert_eq!(tables[0].header[0], ROW);
        assert_eq!(tables[0].key, [ROW]);
        assert_eq!(tables[1].header, [ROW, INDEX, VALUE]);
        assert_eq!(from_tables("p", &tables, &s).unwrap(), msgs);
    }
}
