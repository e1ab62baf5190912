// What `edit_comb.wgsl` and `edit_cut.wgsl` share (CPU side: src/stages/edit_stroke.rs):
// the nearest stroke point and the segment crossing test. Needs the including shader's
// `segs` binding: 8 floats per segment, a.xy ta.xy b.xy tb.xy (image px, unit tangents).

struct Nearest {
    dist: f32,
    dir: vec2<f32>,
}

// Nearest stroke point of `p`: distance and the stroke direction there (end tangents
// interpolated and normalised; the segment's own direction if they cancel). Ties keep
// the first segment.
fn stroke_nearest(p: vec2<f32>, n_segs: u32) -> Nearest {
    var best = 3.0e38;
    var found = false;
    var dir = vec2<f32>(1.0, 0.0);
    for (var i = 0u; i < n_segs; i++) {
        let o = 8u * i;
        let a = vec2<f32>(segs[o], segs[o + 1u]);
        let ta = vec2<f32>(segs[o + 2u], segs[o + 3u]);
        let b = vec2<f32>(segs[o + 4u], segs[o + 5u]);
        let tb = vec2<f32>(segs[o + 6u], segs[o + 7u]);
        let ab = b - a;
        let ap = p - a;
        let l2 = ab.x * ab.x + ab.y * ab.y;
        var u = 0.0;
        if l2 > 0.0 {
            u = clamp((ap.x * ab.x + ap.y * ab.y) / l2, 0.0, 1.0);
        }
        let q = vec2<f32>(ap.x - u * ab.x, ap.y - u * ab.y);
        let d2 = q.x * q.x + q.y * q.y;
        if !found || d2 < best {
            found = true;
            best = d2;
            let t = vec2<f32>(ta.x + u * (tb.x - ta.x), ta.y + u * (tb.y - ta.y));
            let tl = sqrt(t.x * t.x + t.y * t.y);
            let al = sqrt(l2);
            if tl > 1e-6 {
                dir = t / tl;
            } else if al > 0.0 {
                dir = ab / al;
            } else {
                dir = ta;
            }
        }
    }
    if !found {
        return Nearest(3.0e38, dir);
    }
    return Nearest(sqrt(best), dir);
}

fn cross2(o: vec2<f32>, u: vec2<f32>, v: vec2<f32>) -> f32 {
    return (u.x - o.x) * (v.y - o.y) - (u.y - o.y) * (v.x - o.x);
}

// Whether image segments p0-p1 and a-b cross (half-open sign tests, as the mirror).
fn seg_crosses(p0: vec2<f32>, p1: vec2<f32>, a: vec2<f32>, b: vec2<f32>) -> bool {
    let d1 = cross2(a, b, p0) > 0.0;
    let d2 = cross2(a, b, p1) > 0.0;
    let d3 = cross2(p0, p1, a) > 0.0;
    let d4 = cross2(p0, p1, b) > 0.0;
    return d1 != d2 && d3 != d4;
}
