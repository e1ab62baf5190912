// sRGB transfer functions and the HSV adjustment, shared by `strand_shade.wgsl` and
// `render/strand_raster.wgsl`. Mirrored function for function by `src/base/colour.rs`
// (`colour::shader`); the host-side `colour::hsv_adjust` calls that mirror.

fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.0031308 {
        return 12.92 * x;
    }
    return 1.055 * pow(x, 0.41666666) - 0.055;
}

fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.04045 {
        return x / 12.92;
    }
    return pow((x + 0.055) / 1.055, 2.4);
}

// (sextant base 0/2/4, offset in [-1, 1], saturation, value); hue = 60° (base + offset).
fn rgb_to_hsv_split(c: vec3<f32>) -> vec4<f32> {
    let mx = max(max(c.x, c.y), c.z);
    let mn = min(min(c.x, c.y), c.z);
    let ch = mx - mn;
    var s = 0.0;
    if mx > 0.0 {
        s = ch / mx;
    }
    var base = 0.0;
    var off = 0.0;
    if ch <= 0.0 {
        base = 0.0;
    } else if mx == c.x {
        off = (c.y - c.z) / ch;
    } else if mx == c.y {
        base = 2.0;
        off = (c.z - c.x) / ch;
    } else {
        base = 4.0;
        off = (c.x - c.y) / ch;
    }
    return vec4<f32>(base, off, s, mx);
}

fn hsv_split_to_rgb(base: f32, off: f32, s: f32, v: f32) -> vec3<f32> {
    let fl = floor(off);
    let f = off - fl;
    let k = base + fl;
    let sector = k - 6.0 * floor(k / 6.0);
    let p = v - v * s;
    let q = v - v * s * f;
    let t = v - v * s * (1.0 - f);
    if sector < 0.5 {
        return vec3<f32>(v, t, p);
    } else if sector < 1.5 {
        return vec3<f32>(q, v, p);
    } else if sector < 2.5 {
        return vec3<f32>(p, v, t);
    } else if sector < 3.5 {
        return vec3<f32>(p, q, v);
    } else if sector < 4.5 {
        return vec3<f32>(t, p, v);
    }
    return vec3<f32>(v, p, q);
}

fn hsv_adjust_linear(rgb: vec3<f32>, hue_deg: f32, sat: f32, val: f32) -> vec3<f32> {
    let c = vec3<f32>(linear_to_srgb(rgb.x), linear_to_srgb(rgb.y), linear_to_srgb(rgb.z));
    let hsv = rgb_to_hsv_split(c);
    let x = hue_deg / 60.0;
    let xi = floor(x);
    let o = hsv_split_to_rgb(
        hsv.x + xi,
        hsv.y + (x - xi),
        clamp(hsv.z * sat, 0.0, 1.0),
        clamp(hsv.w * val, 0.0, 1.0),
    );
    return vec3<f32>(srgb_to_linear(o.x), srgb_to_linear(o.y), srgb_to_linear(o.z));
}
