//! USD ascii: one linear BasisCurves prim.

use super::*;
use std::fmt::Write as _;

pub(super) fn encode_usda(s: &StrandSet, o: &UsdOptions) -> Msg<Vec<u8>> {
    let name = &o.prim_name;
    let valid_name = name
        .chars()
        .next()
        .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
    if !valid_name {
        return Err(format!("USD prim name {name:?} is not an identifier"));
    }
    if !(o.meters_per_unit.is_finite() && o.meters_per_unit > 0.0) {
        return Err(format!(
            "metersPerUnit {} must be positive",
            o.meters_per_unit
        ));
    }
    if !(o.default_width.is_finite() && o.default_width >= 0.0) {
        return Err(format!("default width {} must be >= 0", o.default_width));
    }
    let up = match o.up_axis {
        UpAxis::Y => "Y",
        UpAxis::Z => "Z",
    };
    let mut t = String::with_capacity(64 + s.points.len() * 48);
    let _ = write!(
        t,
        "#usda 1.0\n(\n    defaultPrim = \"{name}\"\n    doc = \"written by coif: {} strands, {} points\"\n    metersPerUnit = {}\n    upAxis = \"{up}\"\n)\n\n",
        s.counts.len(),
        s.points.len(),
        o.meters_per_unit
    );
    let _ = write!(
        t,
        "def BasisCurves \"{name}\"\n{{\n    uniform token type = \"linear\"\n    uniform token wrap = \"nonperiodic\"\n"
    );
    let list = |t: &mut String, items: &mut dyn Iterator<Item = String>| {
        t.push('[');
        for (i, it) in items.enumerate() {
            if i > 0 {
                t.push_str(", ");
            }
            t.push_str(&it);
        }
        t.push(']');
    };
    let vec3 = |[x, y, z]: [f32; 3]| format!("({x}, {y}, {z})");
    t.push_str("    int[] curveVertexCounts = ");
    list(&mut t, &mut s.counts.iter().map(|c| c.to_string()));
    t.push_str("\n    point3f[] points = ");
    list(&mut t, &mut s.points.iter().map(|&p| vec3(p)));
    t.push_str("\n    float[] widths = ");
    let max_width = match &s.thickness {
        Some(w) => {
            list(&mut t, &mut w.iter().map(|x| x.to_string()));
            t.push_str(" (\n        interpolation = \"vertex\"\n    )\n");
            w.iter().fold(0.0f32, |m, &x| m.max(x))
        }
        None => {
            let _ = write!(
                t,
                "[{}] (\n        interpolation = \"constant\"\n    )\n",
                o.default_width
            );
            o.default_width
        }
    };
    // UsdGeom's curve extent pads the points by half the widest width.
    let (lo, hi) = s.bounds();
    let pad = max_width / 2.0;
    let _ = writeln!(
        t,
        "    float3[] extent = [{}, {}]",
        vec3(lo.map(|v| v - pad)),
        vec3(hi.map(|v| v + pad))
    );
    if let Some(c) = &s.colors {
        t.push_str("    color3f[] primvars:displayColor = ");
        list(&mut t, &mut c.iter().map(|&p| vec3(p)));
        t.push_str(" (\n        interpolation = \"vertex\"\n    )\n");
    }
    if let Some(tr) = &s.transparency {
        t.push_str("    float[] primvars:displayOpacity = ");
        list(&mut t, &mut tr.iter().map(|&x| (1.0 - x).to_string()));
        t.push_str(" (\n        interpolation = \"vertex\"\n    )\n");
    }
    t.push_str("}\n");
    Ok(t.into_bytes())
}

/// A sequence as one USD stage: the BasisCurves' points as time samples (one per frame, the
/// topology of frame 0 for all) and an Xform `head` whose transform follows the head's pose
/// (`head[k]`: row-major rotation and translation, p' = R p + t). Time codes are frames.
pub(super) fn encode_usda_animated(
    frames: &[StrandSet],
    head: &[[f32; 12]],
    fps: f32,
    o: &UsdOptions,
) -> Msg<Vec<u8>> {
    let first = frames.first().ok_or("no frames")?;
    if head.len() != frames.len() {
        return Err(format!(
            "{} head poses for {} frames",
            head.len(),
            frames.len()
        ));
    }
    if !(fps.is_finite() && fps > 0.0) {
        return Err(format!("frame rate {fps} must be positive"));
    }
    for (k, f) in frames.iter().enumerate() {
        f.check().map_err(|m| format!("frame {k}: {m}"))?;
        if f.counts != first.counts {
            return Err(format!("frame {k} has other strands than frame 0"));
        }
    }
    // Frame 0's stage with the union of all frames' bounds as its extent.
    let mut bound = first.clone();
    for f in frames {
        let (lo, hi) = f.bounds();
        bound.points.push(lo);
        bound.points.push(hi);
    }
    let (lo, hi) = bound.bounds();
    let mut base = first.clone();
    base.points[0] = lo;
    if base.points.len() > 1 {
        base.points[1] = hi;
    }
    let text = String::from_utf8(encode_usda(&base, o)?).expect("USD text is UTF-8");
    let start = text.find("    point3f[] points = ").ok_or("no points")?;
    let end = start + text[start..].find('\n').ok_or("no points")?;
    let mut t = String::with_capacity(text.len() * frames.len());
    let header_end = text.find("\n)\n").ok_or("no stage header")?;
    t.push_str(&text[..header_end]);
    let _ = write!(
        t,
        "\n    startTimeCode = 0\n    endTimeCode = {}\n    timeCodesPerSecond = {fps}\n    framesPerSecond = {fps}",
        frames.len() - 1
    );
    t.push_str(&text[header_end..start]);
    t.push_str("    point3f[] points.timeSamples = {\n");
    for (k, f) in frames.iter().enumerate() {
        let _ = write!(t, "        {k}: [");
        for (i, [x, y, z]) in f.points.iter().enumerate() {
            if i > 0 {
                t.push_str(", ");
            }
            let _ = write!(t, "({x}, {y}, {z})");
        }
        t.push_str("],\n");
    }
    t.push_str("    }");
    t.push_str(&text[end..]);
    t.push_str("\ndef Xform \"head\"\n{\n    uniform token[] xformOpOrder = [\"xformOp:transform\"]\n    matrix4d xformOp:transform.timeSamples = {\n");
    for (k, m) in head.iter().enumerate() {
        // USD multiplies row vectors: the rotation goes in transposed, the translation last.
        let _ = writeln!(
            t,
            "        {k}: (({}, {}, {}, 0), ({}, {}, {}, 0), ({}, {}, {}, 0), ({}, {}, {}, 1)),",
            m[0], m[3], m[6], m[1], m[4], m[7], m[2], m[5], m[8], m[9], m[10], m[11]
        );
    }
    t.push_str("    }\n}\n");
    Ok(t.into_bytes())
}
