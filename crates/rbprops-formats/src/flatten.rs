//! Generic, exact mapping between JSON messages and flat CSV tables.
//!
//! Each message (a JSON object) becomes one row. Nested values are flattened into columns
//! named by their path (`com_m.0`, `inertia_cm_kg_m2.1.2`, `products_of_inertia_kg_m2.xy`).
//! A top-level field holding a non-empty array of objects becomes a *child table*
//! `<table>_<field>` whose rows carry `_parent`, the row index of their parent.
//!
//! Cells: numbers as JSON numbers (shortest round-trip form, so floats are bit-exact),
//! booleans `true`/`false`, strings verbatim — unless the text would read back as
//! something else (a number, `true`, `[..]`, an empty string, …), in which case it is
//! written as a JSON string literal (`"42"`). An empty cell means "absent" (null / None),
//! `[]` an empty array, `{}` an empty object.

use serde_json::{Map, Value};

/// Column linking a child row to its parent row.
pub const PARENT: &str = "_parent";

/// Cell prefix of a field whose rows live in a child table (`=> table.csv`); it keeps
/// the field's place among the columns. Strings starting so are written quoted.
pub const CHILD_REF: &str = "=>";

/// One flat table.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    pub name: String,
    /// Parent table and field, for child tables.
    pub parent: Option<(String, String)>,
    pub header: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

/// Text of one scalar cell.
pub fn cell_text(v: &Value) -> String {
    match v {
        Value::String(s) => {
            if s.is_empty()
                || s.trim() != s
                || s.starts_with(CHILD_REF)
                || serde_json::from_str::<Value>(s).is_ok()
            {
                serde_json::to_string(s).expect("string serialises")
            } else {
                s.clone()
            }
        }
        other => other.to_string(),
    }
}

/// Value of one cell (`None` for an empty cell).
pub fn cell_value(text: &str) -> Option<Value> {
    if text.is_empty() {
        return None;
    }
    Some(serde_json::from_str::<Value>(text).unwrap_or_else(|_| Value::String(text.to_string())))
}

fn flatten_inline(path: &str, v: &Value, out: &mut Vec<(String, String)>) {
    match v {
        Value::Null => {}
        Value::Array(a) if a.is_empty() => out.push((path.into(), "[]".into())),
        Value::Object(o) if o.is_empty() => out.push((path.into(), "{}".into())),
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                flatten_inline(&format!("{path}.{i}"), x, out);
            }
        }
        Value::Object(o) => {
            for (k, x) in o {
                flatten_inline(&format!("{path}.{k}"), x, out);
            }
        }
        scalar => out.push((path.into(), cell_text(scalar))),
    }
}

fn is_object_array(v: &Value) -> bool {
    matches!(v, Value::Array(a) if !a.is_empty() && a.iter().all(Value::is_object))
}

/// Flattens messages into a table plus child tables (appended to `out`, parent first).
pub fn to_tables(name: &str, messages: &[Value], out: &mut Vec<Table>) {
    to_tables_inner(
        name,
        None,
        messages.iter().map(|m| (None, m)).collect(),
        out,
    )
}

fn to_tables_inner(
    name: &str,
    parent: Option<(String, String)>,
    rows: Vec<(Option<usize>, &Value)>,
    out: &mut Vec<Table>,
) {
    let mut header: Vec<String> = Vec::new();
    let mut cells: Vec<Vec<(String, String)>> = Vec::new();
    let mut children: Vec<(String, Vec<(Option<usize>, &Value)>)> = Vec::new();
    if parent.is_some() {
        header.push(PARENT.into());
    }
    for (i, (p, v)) in rows.iter().enumerate() {
        let mut row = Vec::new();
        if let Some(p) = p {
            row.push((PARENT.to_string(), p.to_string()));
        }
        match v {
            Value::Object(o) => {
                for (k, x) in o {
                    if is_object_array(x) {
                        let pos = children
                            .iter()
                            .position(|(f, _)| f == k)
                            .unwrap_or_else(|| {
                                children.push((k.clone(), Vec::new()));
                                children.len() - 1
                            });
                        children[pos]
                            .1
                            .extend(x.as_array().unwrap().iter().map(|c| (Some(i), c)));
                        row.push((k.clone(), format!("{CHILD_REF} {name}_{k}.csv")));
                    } else {
                        flatten_inline(k, x, &mut row);
                    }
                }
            }
            other => flatten_inline("value", other, &mut row),
        }
        for (k, _) in &row {
            if !header.contains(k) {
                header.push(k.clone());
            }
        }
        cells.push(row);
    }
    let rows_text = cells
        .into_iter()
        .map(|row| {
            let mut r = vec![String::new(); header.len()];
            for (k, t) in row {
                let j = header.iter().position(|h| *h == k).unwrap();
                r[j] = t;
            }
            r
        })
        .collect();
    out.push(Table {
        name: name.into(),
        parent,
        header,
        rows: rows_text,
    });
    for (field, rows) in children {
        to_tables_inner(
            &format!("{name}_{field}"),
            Some((name.into(), field)),
            rows,
            out,
        );
    }
}

fn set_path(root: &mut Value, path: &[&str], v: Value) -> Result<(), String> {
    let Some((first, rest)) = path.split_first() else {
        *root = v;
        return Ok(());
    };
    if let Ok(i) = first.parse::<usize>() {
        if root.is_null() {
            *root = Value::Array(Vec::new());
        }
        let a = root
            .as_array_mut()
            .ok_or_else(|| format!("'{first}' indexes a non-array"))?;
        if a.len() <= i {
            a.resize(i + 1, Value::Null);
        }
        set_path(&mut a[i], rest, v)
    } else {
        if root.is_null() {
            *root = Value::Object(Map::new());
        }
        let o = root
            .as_object_mut()
            .ok_or_else(|| format!("'{first}' names a field of a non-object"))?;
        set_path(o.entry(first.to_string()).or_insert(Value::Null), rest, v)
    }
}

/// Rebuilds the messages of table `name` (with its child tables from `all`).
/// Errors carry the table name and 1-based data row.
pub fn from_tables(name: &str, all: &[Table]) -> Result<Vec<Value>, String> {
    let t = all
        .iter()
        .find(|t| t.name == name)
        .ok_or_else(|| format!("table {name} missing"))?;
    let mut values = Vec::with_capacity(t.rows.len());
    for (r, row) in t.rows.iter().enumerate() {
        if row.len() != t.header.len() {
            return Err(format!(
                "{name}: row {}: {} cells for {} columns",
                r + 1,
                row.len(),
                t.header.len()
            ));
        }
        let mut v = Value::Object(Map::new());
        for (h, text) in t.header.iter().zip(row) {
            if h == PARENT {
                continue;
            }
            if text.starts_with(CHILD_REF) {
                // Placeholder keeping the field's position; the child table fills it.
                let segs: Vec<&str> = h.split('.').collect();
                set_path(&mut v, &segs, Value::Array(Vec::new()))
                    .map_err(|e| format!("{name}: row {}, column {h}: {e}", r + 1))?;
            } else if let Some(x) = cell_value(text) {
                let segs: Vec<&str> = h.split('.').collect();
                set_path(&mut v, &segs, x)
                    .map_err(|e| format!("{name}: row {}, column {h}: {e}", r + 1))?;
            }
        }
        if t.header.len() == 1 && t.header[0] == "value" {
            v = v.get("value").cloned().unwrap_or(Value::Null);
        }
        values.push(v);
    }
    for child in all
        .iter()
        .filter(|c| c.parent.as_ref().is_some_and(|(p, _)| p == name))
    {
        let field = &child.parent.as_ref().unwrap().1;
        let kids = from_tables(&child.name, all)?;
        let pcol = child
            .header
            .iter()
            .position(|h| h == PARENT)
            .ok_or_else(|| format!("{}: no {PARENT} column", child.name))?;
        for (r, kid) in kids.into_iter().enumerate() {
            let p: usize = child.rows[r][pcol].parse().map_err(|_| {
                format!(
                    "{}: row {}: bad {PARENT} '{}'",
                    child.name,
                    r + 1,
                    child.rows[r][pcol]
                )
            })?;
            let parent = values.get_mut(p).ok_or_else(|| {
                format!(
                    "{}: row {}: {PARENT} {p} has no parent row",
                    child.name,
                    r + 1
                )
            })?;
            let slot = parent
                .as_object_mut()
                .ok_or("child of a non-object")?
                .entry(field.clone())
                .or_insert(Value::Array(Vec::new()));
            slot.as_array_mut()
                .ok_or_else(|| format!("{}: field {field} is not an array", child.name))?
                .push(kid);
        }
    }
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn nested_records_round_trip_exactly() {
        let msgs = vec![
            json!({"a": 0.1, "s": "42", "arrow": "=> x.csv", "e": "", "t": "plain text", "v": [1.0, 2.5e-300], "m": [[1,2],[3,4]], "o": {"x": -0.0}, "kids": [{"k": 1}, {"k": 2, "w": ["x"]}], "empty": [], "none": null}),
            json!({"a": 1e300, "s": "true", "e": " pad", "t": "[oops", "v": [], "m": [[5,6],[7,8]], "o": {"x": 3}, "kids": [], "empty": []}),
        ];
        let mut tables = Vec::new();
        to_tables("topic", &msgs, &mut tables);
        assert_eq!(tables.len(), 2);
        assert_eq!(tables[1].name, "topic_kids");
        let back = from_tables("topic", &tables).unwrap();
        let mut expect = msgs.clone();
        expect[0].as_object_mut().unwrap().remove("none");
        assert_eq!(back, expect);
        assert_eq!(
            back[0]["v"][1].as_f64().unwrap().to_bits(),
            2.5e-300f64.to_bits()
        );
    }
}
