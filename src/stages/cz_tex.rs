//! What the texture passes `cz_lic` and `cz_contrast` share (CZ06 §3.2), the CPU side of
//! `wgsl/shared/cz_tex.wgsl`: the hair domain and sampling over it, written to read like the
//! shader. No stage of its own; the host is `crate::sketch::texture`.

/// floor(x) for |x| < 2²³, as WGSL's `floor`: the truncating cast and a correction
/// (`f32::floor` is a libm call on the baseline x86-64 target, which has no SSE4.1).
#[inline(always)]
pub fn floor(x: f32) -> f32 {
    let t = x as i32 as f32;
    if t > x {
        t - 1.0
    } else {
        t
    }
}

/// The domain and the image a pass samples.
pub struct Domain<'a> {
    pub width: u32,
    pub height: u32,
    /// 1 on the domain (hair with Θ and ρ), 0 elsewhere.
    pub flags: &'a [u32],
    /// (cos Θ, sin Θ) per pixel.
    pub tang: &'a [[f32; 2]],
    pub src: &'a [f32],
}

impl Domain<'_> {
    /// Index of the domain pixel under p, or None off the image or the domain.
    #[inline(always)]
    pub fn pixel(&self, p: [f32; 2]) -> Option<usize> {
        let (fx, fy) = (floor(p[0]), floor(p[1]));
        if fx < 0.0 || fy < 0.0 || fx >= self.width as f32 || fy >= self.height as f32 {
            return None;
        }
        let i = fy as usize * self.width as usize + fx as usize;
        (self.flags[i] != 0).then_some(i)
    }

    /// Calls `f(j, weight)` for each bilinear tap of p on the domain.
    #[inline(always)]
    fn taps(&self, p: [f32; 2], mut f: impl FnMut(usize, f32)) {
        let u = [p[0] - 0.5, p[1] - 0.5];
        let f0 = [floor(u[0]), floor(u[1])];
        let fr = [u[0] - f0[0], u[1] - f0[1]];
        let (x0, y0) = (f0[0] as i32, f0[1] as i32);
        for dy in 0..2 {
            for dx in 0..2 {
                let (xx, yy) = (x0 + dx, y0 + dy);
                if xx >= 0 && yy >= 0 && xx < self.width as i32 && yy < self.height as i32 {
                    let j = yy as usize * self.width as usize + xx as usize;
                    if self.flags[j] != 0 {
                        let wx = if dx == 1 { fr[0] } else { 1.0 - fr[0] };
                        let wy = if dy == 1 { fr[1] } else { 1.0 - fr[1] };
                        f(j, wx * wy);
                    }
                }
            }
        }
    }

    /// Bilinear (Σ w·src, Σ w) over the domain taps around p.
    #[inline(always)]
    pub fn value(&self, p: [f32; 2]) -> [f32; 2] {
        let mut acc = [0.0f32; 2];
        self.taps(p, |j, wt| {
            acc[0] += wt * self.src[j];
            acc[1] += wt;
        });
        acc
    }

    /// The tangent at p, bilinear over the domain taps, each first turned to agree with
    /// `prev`; not normalised, zero when no tap is on the domain.
    #[inline(always)]
    pub fn tangent(&self, p: [f32; 2], prev: [f32; 2]) -> [f32; 2] {
        let mut t = [0.0f32; 2];
        self.taps(p, |j, wt| {
            let mut tj = self.tang[j];
            if tj[0] * prev[0] + tj[1] * prev[1] < 0.0 {
                tj = [-tj[0], -tj[1]];
            }
            t[0] += wt * tj[0];
            t[1] += wt * tj[1];
        });
        t
    }
}
