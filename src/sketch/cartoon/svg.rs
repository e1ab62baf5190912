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
/// `data-kind` (its letter a–e). A path has one fill: in the direction style, the colour at
/// the stroke's middle.
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
        writeln!(
            out,
            "    <path class=\"cz-{k}\" data-curve=\"{}\" data-kind=\"{k}\" fill=\"{}\" d=\"{}\"/>",
            b.curve,
            hex(b.mid_colour()),
            path_data(&b),
            k = b.kind.letter(),
        )
        .unwrap();
    }
    out.push_str("  </g>\n</svg>\n");
    out
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
