//! The cartoon as SVG: one `<path>` per brush, its outline as cubic Béziers (the boundary
//! splines' Catmull-Rom segments converted exactly), arrow-heads as further sub-paths of the
//! same path.

use super::{brushes, Brush, CartoonParams};
use crate::base::colour::linear_to_srgb;
use crate::sketch::Sketch;
use std::fmt::Write;

fn hex(c: [f32; 3]) -> String {
    let b = c.map(linear_to_srgb);
    format!("#{:02x}{:02x}{:02x}", b[0], b[1], b[2])
}

/// A number with at most 3 decimals and no trailing zeros (SVG paths stay short).
fn num(x: f32) -> String {
    let s = format!("{:.3}", x);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" || s.is_empty() {
        "0".into()
    } else {
        s.into()
    }
}

fn pt(p: [f32; 2]) -> String {
    format!("{} {}", num(p[0]), num(p[1]))
}

/// The path data of a brush: the left boundary forward, the right one back, closed; then
/// each arrow-head.
pub fn path_data(b: &Brush) -> String {
    let mut d = String::new();
    if let Some(first) = b.left.first() {
        write!(d, "M {}", pt(first[0])).unwrap();
        for s in &b.left {
            write!(d, " C {} {} {}", pt(s[1]), pt(s[2]), pt(s[3])).unwrap();
        }
        for s in b.right.iter().rev() {
            write!(d, " C {} {} {}", pt(s[2]), pt(s[1]), pt(s[0])).unwrap();
        }
        d.push_str(" Z");
    }
    for (a, _) in &b.arrows {
        write!(d, " M {} L {} L {} Z", pt(a[0]), pt(a[1]), pt(a[2])).unwrap();
    }
    d
}

/// The cartoon on white paper as an SVG document of the sketch's size (viewBox 0 0 W H),
/// one `<path>` per curve in drawing order, with `data-curve` (its index in the sketch) and
/// `data-kind` (its letter a–e). In the direction style a path is filled by a gradient along
/// the stroke (see [`gradient`]).
pub fn to_svg(s: &Sketch, p: &CartoonParams) -> String {
    to_svg_with_backdrop(s, p, None)
}

/// [`to_svg`] over an image referenced by `href` (e.g. the photo's file name next to the
/// SVG) instead of white paper.
pub fn to_svg_with_backdrop(s: &Sketch, p: &CartoonParams, href: Option<&str>) -> String {
    let (w, h) = (s.width, s.height);
    let mut out = String::new();
    out.push_str("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    writeln!(
        out,
        "<svg xmlns=\"http://www.w3.org/2000/svg\" xmlns:xlink=\"http://www.w3.org/1999/xlink\" \
         version=\"1.1\" width=\"{w}\" height=\"{h}\" viewBox=\"0 0 {w} {h}\" \
         data-style=\"{}\" data-width=\"{}\">",
        p.style.name(),
        num(p.width)
    )
    .unwrap();
    out.push_str(
        "  <title>coif cartoon (Chen and Zhu 2006, Fig. 17): one brush stroke per sketch \
         curve</title>\n",
    );
    match href {
        Some(href) => writeln!(
            out,
            "  <image x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" href=\"{0}\" \
             xlink:href=\"{0}\" preserveAspectRatio=\"none\"/>",
            xml_escape(href)
        )
        .unwrap(),
        None => writeln!(
            out,
            "  <rect x=\"0\" y=\"0\" width=\"{w}\" height=\"{h}\" fill=\"#ffffff\"/>"
        )
        .unwrap(),
    }
    out.push_str("  <g id=\"cz-cartoon\" stroke=\"none\" fill-rule=\"nonzero\">\n");
    for b in brushes(s, p) {
        let fill = match gradient(&b) {
            Some(g) => {
                out.push_str(&g);
                format!("url(#cz-g{})", b.curve)
            }
            None => hex(b.mid_colour()),
        };
        writeln!(
            out,
            "    <path class=\"cz-{k}\" data-curve=\"{}\" data-kind=\"{k}\" fill=\"{}\" d=\"{}\"/>",
            b.curve,
            fill,
            path_data(&b),
            k = b.kind.letter(),
        )
        .unwrap();
    }
    out.push_str("  </g>\n</svg>\n");
    out
}

/// A brush whose colour varies along it (the direction style) gets a linear gradient from
/// its start to its end, one stop per boundary segment at the segment's projection on that
/// axis (kept non-decreasing, so a bent stroke's colours stay in order); None for one colour.
fn gradient(b: &Brush) -> Option<String> {
    let first = b.colours.first()?;
    if b.colours.iter().all(|c| c == first) {
        return None;
    }
    let (a, z) = (b.skeleton.first()?[0], b.skeleton.last()?[3]);
    let axis = [z[0] - a[0], z[1] - a[1]];
    let len2 = axis[0] * axis[0] + axis[1] * axis[1];
    if len2 < 1e-6 {
        return None;
    }
    let mut g = format!(
        "    <linearGradient id=\"cz-g{}\" gradientUnits=\"userSpaceOnUse\" x1=\"{}\" y1=\"{}\" \
         x2=\"{}\" y2=\"{}\">",
        b.curve,
        num(a[0]),
        num(a[1]),
        num(z[0]),
        num(z[1])
    );
    let mut last = 0.0f32;
    for (seg, c) in b.left.iter().zip(&b.colours) {
        let m = [0.5 * (seg[0][0] + seg[3][0]), 0.5 * (seg[0][1] + seg[3][1])];
        let t = (((m[0] - a[0]) * axis[0] + (m[1] - a[1]) * axis[1]) / len2).clamp(0.0, 1.0);
        last = last.max(t);
        write!(
            g,
            "<stop offset=\"{}\" stop-color=\"{}\"/>",
            num(last),
            hex(*c)
        )
        .unwrap();
    }
    g.push_str("</linearGradient>\n");
    Some(g)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_short() {
        assert_eq!(num(1.0), "1");
        assert_eq!(num(-0.0001), "0");
        assert_eq!(num(2.5), "2.5");
        assert_eq!(num(1.23456), "1.235");
    }
}
