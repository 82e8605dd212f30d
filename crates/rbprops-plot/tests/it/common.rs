//! Parse-level helpers for checking generated SVG without an XML dependency.
#![allow(dead_code)]

/// One element: tag name, raw attribute text, and text content (for `<text>`).
#[derive(Debug, Clone)]
pub struct Element {
    pub name: String,
    pub attrs: String,
    pub text: String,
}

impl Element {
    pub fn attr(&self, key: &str) -> Option<&str> {
        let pat = format!(" {key}=\"");
        let i = self.attrs.find(&pat)? + pat.len();
        let j = self.attrs[i..].find('"')? + i;
        Some(&self.attrs[i..j])
    }

    pub fn num(&self, key: &str) -> f64 {
        self.attr(key)
            .unwrap_or_else(|| panic!("{} has no {key}", self.name))
            .parse()
            .unwrap()
    }

    /// `points` of a polyline as pixel pairs.
    pub fn points(&self) -> Vec<(i32, i32)> {
        self.attr("points")
            .unwrap_or("")
            .split_whitespace()
            .map(|p| {
                let (x, y) = p.split_once(',').unwrap();
                (x.parse().unwrap(), y.parse().unwrap())
            })
            .collect()
    }
}

/// Checks well-formedness (every opened tag closed in order, single `<svg>`
/// root, no NaN/inf numbers) and returns all elements in document order.
pub fn parse(svg: &str) -> Vec<Element> {
    assert!(svg.starts_with("<svg "), "document must start with <svg");
    assert!(
        svg.trim_end().ends_with("</svg>"),
        "document must end with </svg>"
    );
    for bad in ["NaN", "inf\"", "=\"-inf", "=\"inf"] {
        assert!(!svg.contains(bad), "document contains {bad}");
    }
    let mut out: Vec<Element> = Vec::new();
    let mut stack: Vec<usize> = Vec::new();
    let mut rest = svg;
    while let Some(i) = rest.find('<') {
        let text = &rest[..i];
        if let Some(&open) = stack.last() {
            out[open].text.push_str(text.trim());
        }
        let j = rest[i..].find('>').expect("unterminated tag") + i;
        let tag = &rest[i + 1..j];
        rest = &rest[j + 1..];
        if let Some(name) = tag.strip_prefix('/') {
            let open = stack.pop().expect("closing tag without opening");
            assert_eq!(out[open].name, name.trim(), "mismatched closing tag");
            continue;
        }
        let self_closing = tag.ends_with('/');
        let tag = tag.trim_end_matches('/');
        let (name, attrs) = tag.split_once(' ').unwrap_or((tag, ""));
        assert!(
            name.chars().all(|c| c.is_ascii_alphanumeric()),
            "bad tag name {name:?}"
        );
        out.push(Element {
            name: name.to_string(),
            attrs: format!(" {attrs}"),
            text: String::new(),
        });
        if !self_closing {
            stack.push(out.len() - 1);
        }
    }
    assert!(stack.is_empty(), "unclosed tags");
    assert_eq!(out.iter().filter(|e| e.name == "svg").count(), 1);
    out
}

pub fn with_name<'a>(els: &'a [Element], name: &str) -> Vec<&'a Element> {
    els.iter().filter(|e| e.name == name).collect()
}

/// Elements `name` whose `key` attribute equals `value`.
pub fn with_attr<'a>(els: &'a [Element], name: &str, key: &str, value: &str) -> Vec<&'a Element> {
    els.iter()
        .filter(|e| e.name == name && e.attr(key) == Some(value))
        .collect()
}

/// Text contents of all `<text>` elements.
pub fn texts(els: &[Element]) -> Vec<String> {
    els.iter()
        .filter(|e| e.name == "text")
        .map(|e| e.text.clone())
        .collect()
}

/// Check that `svg` mentions each of `labels` as the full content of a `<text>`.
pub fn assert_has_texts(els: &[Element], labels: &[&str]) {
    let t = texts(els);
    for l in labels {
        assert!(t.iter().any(|x| x == l), "missing text {l:?} in {t:?}");
    }
}
