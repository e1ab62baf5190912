// The parametric head's signed distance in f32, as `src/sim/head_sdf.rs` computes it.
// Needs `head`: the packed primitives of `Head::sdf_packed` bound by the including shader.

fn hv(i: u32) -> vec3<f32> {
    return vec3<f32>(head[i], head[i + 1u], head[i + 2u]);
}

fn sd_ellipsoid(p: vec3<f32>, r: vec3<f32>) -> f32 {
    let k0 = length(p / r);
    let k1 = length(p / r / r);
    let rmin = min(min(r.x, r.y), r.z);
    if k1 < 1e-30 {
        return -rmin;
    }
    let inv_g = k0 / k1;
    if k0 >= 1.0 {
        return (k0 - 1.0) * inv_g;
    }
    let w = k0 * k0 * k0;
    return (k0 - 1.0) * (w * inv_g + (1.0 - w) * rmin);
}

fn sd_capsule(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>, r: f32) -> f32 {
    let pa = p - a;
    let ba = b - a;
    let h = clamp(dot(pa, ba) / max(dot(ba, ba), 1e-18), 0.0, 1.0);
    return length(pa - ba * h) - r;
}

fn sd_rounded_cylinder(p: vec3<f32>, c: vec3<f32>, ra: f32, hh: f32, rb: f32) -> f32 {
    let q = p - c;
    let dx = sqrt(q.x * q.x + q.z * q.z) - ra + rb;
    let dy = abs(q.y) - hh + rb;
    let mx = max(dx, 0.0);
    let my = max(dy, 0.0);
    return min(max(dx, dy), 0.0) + sqrt(mx * mx + my * my) - rb;
}

fn smin(a: f32, b: f32, k: f32) -> f32 {
    let h = max(k - abs(a - b), 0.0) / k;
    return min(a, b) - h * h * k * 0.25;
}

fn head_sdf(p: vec3<f32>) -> f32 {
    let k = head[35];
    var d = sd_ellipsoid(p - hv(0u), hv(3u));
    d = smin(d, sd_ellipsoid(p - hv(6u), hv(9u)), k);
    d = smin(d, sd_ellipsoid(p - hv(12u), hv(15u)), 0.5 * k);
    d = smin(d, sd_capsule(p, hv(18u), hv(21u), head[24]), 0.5 * k);
    let neck = sd_rounded_cylinder(p, hv(30u), head[34], head[33], 0.01);
    d = smin(d, neck, 2.0 * k);
    let pe = vec3<f32>(abs(p.x), p.y, p.z);
    let c = hv(25u);
    let ear = sd_capsule(pe, vec3<f32>(c.x, c.y - head[28], c.z), vec3<f32>(c.x, c.y + head[28], c.z), head[29]);
    return smin(d, ear, head[36]);
}

fn head_sdf_grad(p: vec3<f32>) -> vec3<f32> {
    let e = 5e-4;
    return vec3<f32>(
        head_sdf(p + vec3<f32>(e, 0.0, 0.0)) - head_sdf(p - vec3<f32>(e, 0.0, 0.0)),
        head_sdf(p + vec3<f32>(0.0, e, 0.0)) - head_sdf(p - vec3<f32>(0.0, e, 0.0)),
        head_sdf(p + vec3<f32>(0.0, 0.0, e)) - head_sdf(p - vec3<f32>(0.0, 0.0, e))
    );
}
