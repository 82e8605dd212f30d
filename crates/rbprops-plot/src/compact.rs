//! A smaller text for the same picture: [`compact_svg`] rewrites one of this crate's SVG
//! documents for a page that inlines many of them (`rbprops report`), where the plotters
//! output — one element per grid line, tick and label, each with every attribute spelt
//! out — made a 24-recording campaign's page 26 MB.

/// Curve points closer than this to the line through their kept neighbours are dropped
/// (pixels): half a pixel, below what anti-aliased rendering can show.
pub const CURVE_TOLERANCE_PX: f64 = 0.5;

/// Rewrites an SVG document written by this crate's plots (plotters' SVG backend: one
/// element per line) so that it draws the same picture in fewer bytes:
///
/// - attributes equal to their SVG default are dropped (`opacity="1"`,
///   `stroke-width="1"`, a text's `fill="#000000"`, a rectangle's `stroke="none"`), the font family is said once on the
///   root element, font sizes keep two decimals (0.005 px), a label's shift in `em` is
///   folded into its `y` (to 0.01 px), label text loses the line breaks around it
///   (which SVG does not render);
/// - runs of grid lines with the same style and orientation become one `<path>` (parallel
///   lines do not overlap, so a translucent grid composites as before); opaque two-point
///   segments of one style (tick marks, axis lines) become one `<path>` at the first
///   one's place, moved only past labels (which they do not touch);
/// - each remaining polyline becomes a `<path>` of relative steps, and drops repeated pixels and the points within
///   [`CURVE_TOLERANCE_PX`] of the line through the points kept around them
///   (Douglas–Peucker), always keeping its first, last, topmost and bottommost points —
///   so a curve's peak (the largest |H| of an FRF, the top of its drawing) stays exactly
///   where it was.
///
/// Other elements (rectangles, circles, anything unexpected) are copied unchanged, and a
/// document that is not one `<svg …>` element per line comes back as it was.
pub fn compact_svg(svg: &str) -> String {
    let Some(items) = parse(svg) else {
        return svg.to_string();
    };
    let merged = merge_segments(items);
    let mut out = String::with_capacity(svg.len() / 3);
    let mut i = 0;
    while i < merged.len() {
        // Consecutive labels with the same anchor and size share them through a group.
        if let Item::Text { attrs, .. } = &merged[i] {
            let shared = (attr(attrs, "text-anchor"), attr(attrs, "font-size"));
            let mut j = i + 1;
            while j < merged.len()
                && matches!(&merged[j], Item::Text { attrs, .. }
                    if (attr(attrs, "text-anchor"), attr(attrs, "font-size")) == shared)
            {
                j += 1;
            }
            if j - i >= 2 && shared.0.is_some() && shared.1.is_some() {
                out.push_str(&format!(
                    "<g text-anchor=\"{}\" font-size=\"{}\">\n",
                    shared.0.unwrap(),
                    shared.1.unwrap()
                ));
                for it in &merged[i..j] {
                    if let Item::Text { attrs, content } = it {
                        let a = without(&without(attrs, "text-anchor"), "font-size");
                        out.push_str(&format!("<text{a}>{content}</text>\n"));
                    }
                }
                out.push_str("</g>\n");
                i = j;
                continue;
            }
        }
        merged[i].write(&mut out);
        i += 1;
    }
    out
}

/// One element of the document.
#[derive(Debug, Clone)]
enum Item {
    /// Copied as it is (the root tag, `</svg>`, rectangles, …).
    Raw(String),
    /// A `<line>`: its attributes other than the coordinates, and the coordinates.
    Line { attrs: String, xy: [i64; 4] },
    /// A `<polyline>`: its attributes other than `points`, and the points.
    Polyline {
        attrs: String,
        points: Vec<(i64, i64)>,
    },
    /// A `<text>`: attributes (with a leading space) and content.
    Text { attrs: String, content: String },
    /// Several segments of one style drawn as one `<path>`; `end` is the current point
    /// of its data `d`.
    Path {
        attrs: String,
        d: String,
        end: (i64, i64),
    },
}

impl Item {
    fn write(&self, out: &mut String) {
        match self {
            Item::Raw(s) => out.push_str(s),
            Item::Line { attrs, xy } => out.push_str(&format!(
                "<line{attrs} x1=\"{}\" y1=\"{}\" x2=\"{}\" y2=\"{}\"/>",
                xy[0], xy[1], xy[2], xy[3]
            )),
            Item::Polyline { attrs, points } => {
                out.push_str(&format!("<path{attrs} d=\"{}\"/>", relative_path(points)))
            }
            Item::Text { attrs, content } => {
                out.push_str(&format!("<text{attrs}>{content}</text>"))
            }
            Item::Path { attrs, d, .. } => out.push_str(&format!("<path{attrs} d=\"{d}\"/>")),
        }
        out.push('\n');
    }
}

/// Splits plotters' output into elements, cleaning their attributes; `None` when the
/// text is not laid out as expected.
fn parse(svg: &str) -> Option<Vec<Item>> {
    let mut lines = svg.lines();
    let root = lines.next()?;
    if !root.starts_with("<svg ") || !root.ends_with('>') {
        return None;
    }
    let mut items = vec![Item::Raw(String::new())];
    let mut family: Option<String> = None;
    while let Some(line) = lines.next() {
        if let Some(rest) = line.strip_prefix("<text") {
            // `<text …>`, then the content lines, then `</text>`.
            let attrs = rest.strip_suffix('>')?;
            let mut content = Vec::new();
            loop {
                let l = lines.next()?;
                if l == "</text>" {
                    break;
                }
                content.push(l);
            }
            if let Some(f) = attr(attrs, "font-family") {
                match &family {
                    None => family = Some(f.to_string()),
                    Some(g) if g != f => return None,
                    _ => {}
                }
            }
            let mut a = without(&clean(attrs), "font-family");
            if attr(&a, "fill") == Some("#000000") {
                a = without(&a, "fill");
            }
            items.push(Item::Text {
                attrs: round_font_size(&fold_em_shift(&a)),
                content: content.join("\n"),
            });
        } else if let Some(rest) = line.strip_prefix("<line") {
            let attrs = rest.strip_suffix("/>")?;
            let n = |k: &str| attr(attrs, k).and_then(|v| v.parse::<i64>().ok());
            let xy = [n("x1")?, n("y1")?, n("x2")?, n("y2")?];
            let mut a = clean(attrs);
            for k in ["x1", "y1", "x2", "y2"] {
                a = without(&a, k);
            }
            items.push(Item::Line { attrs: a, xy });
        } else if let Some(rest) = line.strip_prefix("<polyline") {
            let attrs = rest.strip_suffix("/>")?;
            let points = attr(attrs, "points")?
                .split_whitespace()
                .map(|p| {
                    let (x, y) = p.split_once(',')?;
                    Some((x.parse().ok()?, y.parse().ok()?))
                })
                .collect::<Option<Vec<(i64, i64)>>>()?;
            items.push(Item::Polyline {
                attrs: without(&clean(attrs), "points"),
                points: thin_curve(&points, CURVE_TOLERANCE_PX),
            });
        } else if line.starts_with("<rect") || line.starts_with("<circle") {
            // No stroke is the default (and nothing above sets one).
            let a = clean(line);
            items.push(Item::Raw(match attr(&a, "stroke") {
                Some("none") => without(&a, "stroke"),
                _ => a,
            }));
        } else {
            items.push(Item::Raw(line.to_string()));
        }
    }
    items[0] = Item::Raw(match family {
        Some(f) => format!("{} font-family=\"{f}\">", root.strip_suffix('>')?),
        None => root.to_string(),
    });
    Some(items)
}

/// The value of attribute `key` in an attribute string.
fn attr<'a>(attrs: &'a str, key: &str) -> Option<&'a str> {
    let pat = format!(" {key}=\"");
    let start = attrs.find(&pat)? + pat.len();
    let len = attrs[start..].find('"')?;
    Some(&attrs[start..start + len])
}

/// The attribute string without attribute `key`.
fn without(attrs: &str, key: &str) -> String {
    let pat = format!(" {key}=\"");
    match attrs.find(&pat) {
        Some(start) => {
            let vstart = start + pat.len();
            match attrs[vstart..].find('"') {
                Some(len) => format!("{}{}", &attrs[..start], &attrs[vstart + len + 1..]),
                None => attrs.to_string(),
            }
        }
        None => attrs.to_string(),
    }
}

/// Drops the attributes that repeat the SVG default.
fn clean(attrs: &str) -> String {
    let mut a = attrs.to_string();
    for (k, v) in [("opacity", "1"), ("stroke-width", "1")] {
        if attr(&a, k) == Some(v) {
            a = without(&a, k);
        }
    }
    a
}

/// `font-size` with two decimals (plotters writes sixteen).
fn round_font_size(attrs: &str) -> String {
    match attr(attrs, "font-size").and_then(|v| v.parse::<f64>().ok()) {
        Some(v) => {
            let short = format!("{v:.2}");
            let short = short.trim_end_matches('0').trim_end_matches('.');
            without(attrs, "font-size") + &format!(" font-size=\"{short}\"")
        }
        None => attrs.to_string(),
    }
}

/// A shift `dy` in `em` folded into `y` (`0.76em` at 12.9 px is 9.81 px; to 0.01 px).
fn fold_em_shift(attrs: &str) -> String {
    let em = attr(attrs, "dy").and_then(|d| d.strip_suffix("em")?.parse::<f64>().ok());
    let size = attr(attrs, "font-size").and_then(|v| v.parse::<f64>().ok());
    let y = attr(attrs, "y").and_then(|v| v.parse::<f64>().ok());
    match (em, size, y) {
        (Some(em), Some(size), Some(y)) => {
            let moved = format!("{:.2}", y + em * size);
            let moved = moved.trim_end_matches('0').trim_end_matches('.');
            let a = without(attrs, "dy");
            a.replacen(
                &format!(" y=\"{}\"", attr(attrs, "y").unwrap()),
                &format!(" y=\"{moved}\""),
                1,
            )
        }
        _ => attrs.to_string(),
    }
}

/// A segment that may join others of its style in one path: a line or a two-point
/// polyline, with `true` when it is opaque (no `opacity` left after [`clean`]). A path
/// of separate straight segments encloses no area, so it needs no `fill="none"`.
fn segment(item: &Item) -> Option<(String, [i64; 4], bool)> {
    let (attrs, xy) = match item {
        Item::Line { attrs, xy } => (attrs.clone(), *xy),
        Item::Polyline { attrs, points } if points.len() == 2 => (
            if attrs.contains(" fill=\"none\"") {
                without(attrs, "fill")
            } else {
                return None;
            },
            [points[0].0, points[0].1, points[1].0, points[1].1],
        ),
        _ => return None,
    };
    let opaque = attr(&attrs, "opacity").is_none();
    Some((attrs, xy, opaque))
}

/// Two numbers of path data: a minus sign separates them, a space otherwise.
fn pair(a: i64, b: i64) -> String {
    if b < 0 {
        format!("{a}{b}")
    } else {
        format!("{a} {b}")
    }
}

/// Path data of a polyline: the first point, then each step from the previous point
/// (`l dx dy`, `h dx`, `v dy`), which is shorter than absolute pairs.
fn relative_path(points: &[(i64, i64)]) -> String {
    let Some(&(x0, y0)) = points.first() else {
        return String::new();
    };
    let mut d = format!("M{x0} {y0}");
    let mut last = ' ';
    for w in points.windows(2) {
        let (dx, dy) = (w[1].0 - w[0].0, w[1].1 - w[0].1);
        let (cmd, args) = match (dx, dy) {
            (_, 0) => ('h', format!("{dx}")),
            (0, _) => ('v', format!("{dy}")),
            _ => ('l', pair(dx, dy)),
        };
        // A repeated command may be left out; a number then needs a separator unless
        // it starts with its minus sign.
        if cmd != last {
            d.push(cmd);
        } else if !args.starts_with('-') {
            d.push(' ');
        }
        d.push_str(&args);
        last = cmd;
    }
    d
}

/// Path data drawing segment `xy` after a path whose current point is `from` (`None`:
/// the first segment), and the new current point. The move is relative when there is a
/// current point (`m30 0` to the next grid line); an undashed segment is drawn from its
/// end nearer the current point (a grid of parallel lines becomes a meander of moves);
/// vertical and horizontal segments use `V` and `H`.
fn segment_d(xy: [i64; 4], from: Option<(i64, i64)>, reversible: bool) -> (String, (i64, i64)) {
    let [mut x1, mut y1, mut x2, mut y2] = xy;
    let mut d = match from {
        None => format!("M{x1} {y1}"),
        Some((cx, cy)) => {
            let dist = |x: i64, y: i64| (x - cx).abs() + (y - cy).abs();
            if reversible && dist(x2, y2) < dist(x1, y1) {
                (x1, y1, x2, y2) = (x2, y2, x1, y1);
            }
            format!("m{}", pair(x1 - cx, y1 - cy))
        }
    };
    if x1 == x2 {
        d.push_str(&format!("V{y2}"));
    } else if y1 == y2 {
        d.push_str(&format!("H{x2}"));
    } else {
        d.push_str(&format!("l{}", pair(x2 - x1, y2 - y1)));
    }
    (d, (x2, y2))
}

/// Joins segments of one style into paths: translucent ones only while they follow each
/// other with one orientation (parallel, so none is painted over another); opaque ones
/// also past labels, the path standing where the first of them stood.
fn merge_segments(items: Vec<Item>) -> Vec<Item> {
    let mut out: Vec<Item> = Vec::with_capacity(items.len());
    // Open groups: (attrs, index in `out`, orientation for translucent groups).
    let mut open: Vec<(String, usize, Option<bool>)> = Vec::new();
    for item in items {
        let Some((attrs, xy, opaque)) = segment(&item) else {
            // A label keeps opaque groups open; anything else closes every group.
            if matches!(item, Item::Text { .. }) {
                open.retain(|g| g.2.is_none());
            } else {
                open.clear();
            }
            out.push(item);
            continue;
        };
        let vertical = xy[0] == xy[2];
        let orientation = (!opaque).then_some(vertical);
        // A segment closes every group but its own: nothing is moved past a drawing
        // of another style.
        open.retain(|g| g.0 == attrs && g.2 == orientation);
        let reversible = !attrs.contains("stroke-dasharray");
        match open
            .iter()
            .find(|g| g.0 == attrs && g.2 == orientation)
            .map(|g| g.1)
        {
            Some(k) => {
                if let Item::Path { d, end, .. } = &mut out[k] {
                    let (more, to) = segment_d(xy, Some(*end), reversible);
                    d.push_str(&more);
                    *end = to;
                }
            }
            None => {
                open.push((attrs.clone(), out.len(), orientation));
                let (d, end) = segment_d(xy, None, reversible);
                out.push(Item::Path { attrs, d, end });
            }
        }
    }
    out
}

/// A polyline without repeated points and without the points within `tol` of the
/// straight line through the points kept around them (Douglas–Peucker), keeping the
/// first, last, topmost and bottommost points.
fn thin_curve(points: &[(i64, i64)], tol: f64) -> Vec<(i64, i64)> {
    let mut q: Vec<(i64, i64)> = Vec::with_capacity(points.len());
    for &p in points {
        if q.last() != Some(&p) {
            q.push(p);
        }
    }
    if q.len() < 3 {
        return q;
    }
    let n = q.len();
    let top = (0..n).min_by_key(|&i| (q[i].1, i)).unwrap_or(0);
    let bottom = (0..n).min_by_key(|&i| (-q[i].1, i)).unwrap_or(0);
    let mut keep = vec![false; n];
    let mut anchors = vec![0, top, bottom, n - 1];
    anchors.sort_unstable();
    anchors.dedup();
    for &a in &anchors {
        keep[a] = true;
    }
    let mut stack: Vec<(usize, usize)> = anchors.windows(2).map(|w| (w[0], w[1])).collect();
    while let Some((a, b)) = stack.pop() {
        if b <= a + 1 {
            continue;
        }
        let (far, dist) = (a + 1..b)
            .map(|i| (i, distance_to_segment(q[i], q[a], q[b])))
            .fold((a, -1.0), |best, c| if c.1 > best.1 { c } else { best });
        if dist > tol {
            keep[far] = true;
            stack.push((a, far));
            stack.push((far, b));
        }
    }
    q.into_iter()
        .zip(keep)
        .filter_map(|(p, k)| k.then_some(p))
        .collect()
}

/// Distance (pixels) from `p` to the segment `a`–`b`.
fn distance_to_segment(p: (i64, i64), a: (i64, i64), b: (i64, i64)) -> f64 {
    let (px, py) = (p.0 as f64, p.1 as f64);
    let (ax, ay) = (a.0 as f64, a.1 as f64);
    let (dx, dy) = (b.0 as f64 - ax, b.1 as f64 - ay);
    let l2 = dx * dx + dy * dy;
    let t = if l2 > 0.0 {
        (((px - ax) * dx + (py - ay) * dy) / l2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    ((px - ax - t * dx).powi(2) + (py - ay - t * dy).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_ends_and_extremes_and_stays_within_tolerance() {
        // A ramp drawn in whole pixels, with one spike.
        let pts: Vec<(i64, i64)> = (0..400)
            .map(|i| (i / 2, 300 - i / 3 - if i == 251 { 120 } else { 0 }))
            .collect();
        let thin = thin_curve(&pts, CURVE_TOLERANCE_PX);
        // Two points per pixel column: dropping repeats alone leaves 200.
        assert!(thin.len() < 150, "{}", thin.len());
        assert_eq!(thin.first(), pts.first());
        assert_eq!(thin.last(), pts.last());
        let top = pts.iter().map(|p| p.1).min().unwrap();
        let bottom = pts.iter().map(|p| p.1).max().unwrap();
        assert!(thin.iter().any(|p| p.1 == top) && thin.iter().any(|p| p.1 == bottom));
        // Every dropped point lies within the tolerance of the drawn line.
        for p in &pts {
            let d = thin
                .windows(2)
                .map(|w| distance_to_segment(*p, w[0], w[1]))
                .fold(f64::INFINITY, f64::min);
            assert!(d <= CURVE_TOLERANCE_PX, "{p:?} is {d} px off");
        }
    }

    #[test]
    fn grid_ticks_and_labels_are_merged_without_reordering_what_overlaps() {
        let svg = "<svg width=\"10\" height=\"10\" viewBox=\"0 0 10 10\" xmlns=\"http://www.w3.org/2000/svg\">\n\
<rect x=\"0\" y=\"0\" width=\"10\" height=\"10\" opacity=\"1\" fill=\"#FFFFFF\" stroke=\"none\"/>\n\
<line opacity=\"0.05\" stroke=\"#000000\" stroke-width=\"1\" x1=\"1\" y1=\"9\" x2=\"1\" y2=\"0\"/>\n\
<line opacity=\"0.05\" stroke=\"#000000\" stroke-width=\"1\" x1=\"3\" y1=\"9\" x2=\"3\" y2=\"0\"/>\n\
<line opacity=\"0.05\" stroke=\"#000000\" stroke-width=\"1\" x1=\"0\" y1=\"4\" x2=\"9\" y2=\"4\"/>\n\
<polyline fill=\"none\" opacity=\"1\" stroke=\"#000000\" stroke-width=\"1\" points=\"1,9 1,10 \"/>\n\
<text x=\"1\" y=\"10\" dy=\"0.76em\" text-anchor=\"middle\" font-family=\"sans-serif\" font-size=\"12.903225806451612\" opacity=\"1\" fill=\"#000000\">\n\
1\n\
</text>\n\
<polyline fill=\"none\" opacity=\"1\" stroke=\"#000000\" stroke-width=\"1\" points=\"3,9 3,10 \"/>\n\
<text x=\"3\" y=\"10\" dy=\"0.76em\" text-anchor=\"middle\" font-family=\"sans-serif\" font-size=\"12.903225806451612\" opacity=\"1\" fill=\"#000000\">\n\
2\n\
</text>\n\
<polyline fill=\"none\" opacity=\"1\" stroke=\"#1F77B4\" stroke-width=\"2\" points=\"0,5 1,5 2,5 3,2 \"/>\n\
</svg>";
        let c = compact_svg(svg);
        assert_eq!(
            c,
            "<svg width=\"10\" height=\"10\" viewBox=\"0 0 10 10\" xmlns=\"http://www.w3.org/2000/svg\" font-family=\"sans-serif\">\n\
<rect x=\"0\" y=\"0\" width=\"10\" height=\"10\" fill=\"#FFFFFF\"/>\n\
<path opacity=\"0.05\" stroke=\"#000000\" d=\"M1 9V0m2 0V9\"/>\n\
<path opacity=\"0.05\" stroke=\"#000000\" d=\"M0 4H9\"/>\n\
<path stroke=\"#000000\" d=\"M1 9V10m2 0V9\"/>\n\
<g text-anchor=\"middle\" font-size=\"12.9\">\n\
<text x=\"1\" y=\"19.81\">1</text>\n\
<text x=\"3\" y=\"19.81\">2</text>\n\
</g>\n\
<path fill=\"none\" stroke=\"#1F77B4\" stroke-width=\"2\" d=\"M0 5h2l1-3\"/>\n\
</svg>\n"
        );
        // Not plotters' layout: unchanged.
        let other = "<svg><rect/></svg>";
        assert_eq!(compact_svg(other), other);
    }
}
