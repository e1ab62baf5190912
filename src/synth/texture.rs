//! Texture variations of the 2D synthetic portrait: how the strands are drawn (width,
//! contrast, curl) and how the finished picture is degraded (blur, noise, JPEG), so the
//! orientation and direction stages are measured on hair the default look does not draw.
//!
//! Curl changes the growth field itself (the strands and the ground truth follow the same
//! curled field); the other variations change pixels only, so the ground truth stays the
//! analytic field and mask at every pixel centre.

use crate::base::rng::Rng;
use crate::error::{Error, Result};
use std::str::FromStr;

/// How a synthetic portrait's hair is drawn and degraded. [`Texture::default`] is the look
/// every existing test and golden uses.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Texture {
    /// Strand width factor (1: 1-1.5 px at 512²).
    pub width: f32,
    /// Strand contrast factor: scales each strand's opacity and its brightness spread
    /// (1: opacity 0.6-0.95 over the dark base fill).
    pub contrast: f32,
    /// Sigma of additive Gaussian noise per channel, in [0, 1] colour units.
    pub noise: f32,
    /// Sigma of a Gaussian blur of the finished picture, px.
    pub blur: f32,
    /// Quality (1..=100) of a JPEG encode and decode of the finished picture; 0: none.
    pub jpeg: u8,
    /// Largest turn the curl adds to the growth field, degrees; 0: none.
    pub curl: f32,
    /// Wavelength of the curl along a strand, px at 512² (scaled with the size).
    pub curl_wavelength: f32,
}

impl Default for Texture {
    fn default() -> Self {
        Texture {
            width: 1.0,
            contrast: 1.0,
            noise: 0.0,
            blur: 0.0,
            jpeg: 0,
            curl: 0.0,
            curl_wavelength: 60.0,
        }
    }
}

/// Named variations: `coif synth --texture NAME` and the variations test.
pub const PRESETS: [(&str, &str); 9] = [
    ("plain", ""),
    ("thin", "width=0.7"),
    ("thick", "width=2.2"),
    ("faint", "contrast=0.45"),
    ("noisy", "noise=0.04"),
    ("blurry", "blur=0.9"),
    ("jpeg", "jpeg=65"),
    ("curly", "curl=20,wavelength=48"),
    // Several at once, like a web photo of wavy hair.
    (
        "photo",
        "width=1.6,contrast=0.7,noise=0.02,blur=0.5,jpeg=70,curl=12",
    ),
];

impl Texture {
    /// Whether this is the default look (no variation).
    pub fn is_plain(&self) -> bool {
        *self == Texture::default()
    }

    /// `key=value` pairs of the fields that differ from the default ("plain" for none); it
    /// parses back to the same texture.
    pub fn label(&self) -> String {
        let d = Texture::default();
        let mut parts = Vec::new();
        if self.width != d.width {
            parts.push(format!("width={}", self.width));
        }
        if self.contrast != d.contrast {
            parts.push(format!("contrast={}", self.contrast));
        }
        if self.noise != d.noise {
            parts.push(format!("noise={}", self.noise));
        }
        if self.blur != d.blur {
            parts.push(format!("blur={}", self.blur));
        }
        if self.jpeg != d.jpeg {
            parts.push(format!("jpeg={}", self.jpeg));
        }
        if self.curl != d.curl {
            parts.push(format!("curl={}", self.curl));
        }
        if self.curl_wavelength != d.curl_wavelength {
            parts.push(format!("wavelength={}", self.curl_wavelength));
        }
        if parts.is_empty() {
            "plain".into()
        } else {
            parts.join(",")
        }
    }

    fn check(&self) -> Result<()> {
        let bad = |m: String| Err(Error::Invalid(format!("--texture: {m}")));
        if !(self.width.is_finite() && (0.3..=4.0).contains(&self.width)) {
            return bad(format!("width {} is outside 0.3..=4", self.width));
        }
        if !(self.contrast.is_finite() && (0.1..=1.0).contains(&self.contrast)) {
            return bad(format!("contrast {} is outside 0.1..=1", self.contrast));
        }
        if !(self.noise.is_finite() && (0.0..=0.3).contains(&self.noise)) {
            return bad(format!("noise {} is outside 0..=0.3", self.noise));
        }
        if !(self.blur.is_finite() && (0.0..=4.0).contains(&self.blur)) {
            return bad(format!("blur {} is outside 0..=4", self.blur));
        }
        if self.jpeg > 100 {
            return bad(format!("jpeg {} is outside 0..=100", self.jpeg));
        }
        if !(self.curl.is_finite() && (0.0..=40.0).contains(&self.curl)) {
            return bad(format!("curl {} is outside 0..=40 degrees", self.curl));
        }
        if !(self.curl_wavelength.is_finite() && (16.0..=400.0).contains(&self.curl_wavelength)) {
            return bad(format!(
                "wavelength {} is outside 16..=400 px",
                self.curl_wavelength
            ));
        }
        Ok(())
    }
}

impl FromStr for Texture {
    type Err = Error;

    /// A comma-separated list of preset names and `key=value` pairs, applied in order:
    /// "curly", "jpeg=70", "thick,noise=0.03". Keys: width, contrast, noise, blur, jpeg,
    /// curl, wavelength.
    fn from_str(s: &str) -> Result<Texture> {
        let mut t = Texture::default();
        apply(&mut t, s)?;
        t.check()?;
        Ok(t)
    }
}

fn apply(t: &mut Texture, s: &str) -> Result<()> {
    for item in s.split(',').map(str::trim).filter(|i| !i.is_empty()) {
        let Some((key, value)) = item.split_once('=') else {
            let Some((_, spec)) = PRESETS.iter().find(|(n, _)| *n == item) else {
                let names: Vec<&str> = PRESETS.iter().map(|(n, _)| *n).collect();
                return Err(Error::Invalid(format!(
                    "--texture: unknown variation \"{item}\" (expected one of {}, or \
                     key=value with keys width, contrast, noise, blur, jpeg, curl, wavelength)",
                    names.join(", ")
                )));
            };
            apply(t, spec)?;
            continue;
        };
        let num = |v: &str| -> Result<f32> {
            v.trim()
                .parse::<f32>()
                .map_err(|_| Error::Invalid(format!("--texture: {key}={v} is not a number")))
        };
        match key.trim() {
            "width" => t.width = num(value)?,
            "contrast" => t.contrast = num(value)?,
            "noise" => t.noise = num(value)?,
            "blur" => t.blur = num(value)?,
            "jpeg" => {
                t.jpeg = value.trim().parse::<u8>().map_err(|_| {
                    Error::Invalid(format!("--texture: jpeg={value} is not a quality 0..=100"))
                })?
            }
            "curl" => t.curl = num(value)?,
            "wavelength" => t.curl_wavelength = num(value)?,
            other => {
                return Err(Error::Invalid(format!(
                    "--texture: unknown key \"{other}\" (keys: width, contrast, noise, blur, \
                     jpeg, curl, wavelength)"
                )))
            }
        }
    }
    Ok(())
}

impl std::fmt::Display for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.label())
    }
}

/// The curl's rotation of the growth field: two plane waves across the image, one along
/// each axis, so a strand running any way meets about one turn per wavelength.
#[derive(Clone, Debug)]
pub(super) struct Curl {
    amp: f32,
    k: f32,
    phase: [f32; 2],
}

impl Curl {
    /// None for a texture without curl. `s` is the portrait's length unit (1 at 512²).
    pub(super) fn new(t: &Texture, s: f32, rng: &mut Rng) -> Option<Curl> {
        (t.curl > 0.0).then(|| Curl {
            amp: t.curl.to_radians(),
            k: std::f32::consts::TAU / (t.curl_wavelength * s),
            phase: [
                rng.range_f32(0.0, std::f32::consts::TAU),
                rng.range_f32(0.0, std::f32::consts::TAU),
            ],
        })
    }

    /// The angle the field is turned by at (x, y), radians; smooth, within ±amp.
    pub(super) fn angle(&self, x: f32, y: f32) -> f32 {
        0.5 * self.amp * ((self.k * x + self.phase[0]).sin() + (self.k * y + self.phase[1]).sin())
    }
}

/// Blur and noise on the linear [0, 1] picture before it is quantised.
pub(super) fn degrade(rgb: &mut [[f32; 3]], w: usize, h: usize, t: &Texture, rng: &mut Rng) {
    if t.blur > 0.0 {
        gaussian_blur(rgb, w, h, t.blur);
    }
    if t.noise > 0.0 {
        for c in rgb.iter_mut() {
            for v in c.iter_mut() {
                *v += t.noise * rng.normal_f32();
            }
        }
    }
}

/// A JPEG encode and decode at quality `q`, as a photo from the web has been through.
pub(crate) fn jpeg_round_trip(img: &image::RgbImage, q: u8) -> image::RgbImage {
    let mut buf = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut buf, q.max(1))
        .encode_image(img)
        .expect("encoding an RGB image into memory cannot fail");
    image::load_from_memory_with_format(&buf, image::ImageFormat::Jpeg)
        .expect("the encoder's own output decodes")
        .to_rgb8()
}

/// Separable Gaussian blur (radius 3σ, edges clamped).
fn gaussian_blur(rgb: &mut [[f32; 3]], w: usize, h: usize, sigma: f32) {
    let r = (3.0 * sigma).ceil().max(1.0) as i64;
    let mut k: Vec<f32> = (-r..=r)
        .map(|d| (-(d * d) as f32 / (2.0 * sigma * sigma)).exp())
        .collect();
    let sum: f32 = k.iter().sum();
    k.iter_mut().for_each(|v| *v /= sum);
    let mut tmp = vec![[0.0f32; 3]; w * h];
    for (pass, (step, n)) in [(1usize, w), (w, h)].into_iter().enumerate() {
        let (from, to): (&[[f32; 3]], &mut [[f32; 3]]) = if pass == 0 {
            (&*rgb, &mut tmp)
        } else {
            // Second pass reads tmp and writes back into rgb.
            (&tmp, &mut *rgb)
        };
        for (i, o) in to.iter_mut().enumerate() {
            let along = if step == 1 { i % w } else { i / w } as i64;
            let mut acc = [0.0f32; 3];
            for (j, &kv) in k.iter().enumerate() {
                let a = (along + j as i64 - r).clamp(0, n as i64 - 1);
                let src = &from[(i as i64 + (a - along) * step as i64) as usize];
                for c in 0..3 {
                    acc[c] += kv * src[c];
                }
            }
            *o = acc;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_parse_and_labels_round_trip() {
        for (name, _) in PRESETS {
            let t: Texture = name.parse().unwrap();
            assert_eq!(t.label().parse::<Texture>().unwrap(), t, "{name}");
            assert_eq!(t.is_plain(), name == "plain", "{name}");
        }
        let t: Texture = "curly,jpeg=70".parse().unwrap();
        assert_eq!((t.curl, t.curl_wavelength, t.jpeg), (20.0, 48.0, 70));
    }

    #[test]
    fn bad_textures_name_the_problem() {
        for (s, want) in [
            ("wobbly", "unknown variation \"wobbly\""),
            ("width=x", "width=x is not a number"),
            ("colour=1", "unknown key \"colour\""),
            ("jpeg=300", "jpeg=300 is not a quality"),
            ("noise=2", "noise 2 is outside"),
            ("contrast=0", "contrast 0 is outside"),
        ] {
            let e = s.parse::<Texture>().unwrap_err().to_string();
            assert!(e.contains(want), "{s}: {e}");
        }
    }

    #[test]
    fn blur_keeps_a_constant_and_spreads_a_dot() {
        let (w, h) = (9, 7);
        let mut flat = vec![[0.25f32; 3]; w * h];
        gaussian_blur(&mut flat, w, h, 1.0);
        assert!(flat.iter().all(|c| (c[0] - 0.25).abs() < 1e-5));
        let mut dot = vec![[0.0f32; 3]; w * h];
        dot[3 * w + 4] = [1.0; 3];
        gaussian_blur(&mut dot, w, h, 1.0);
        let total: f32 = dot.iter().map(|c| c[0]).sum();
        assert!((total - 1.0).abs() < 1e-4, "mass {total}");
        assert!(dot[3 * w + 4][0] < 0.2 && dot[3 * w + 5][0] > 0.05);
        assert!((dot[3 * w + 3][0] - dot[3 * w + 5][0]).abs() < 1e-6);
        assert!((dot[2 * w + 4][0] - dot[4 * w + 4][0]).abs() < 1e-6);
    }

    #[test]
    fn curl_turns_within_its_amplitude() {
        let t: Texture = "curl=20".parse().unwrap();
        let c = Curl::new(&t, 1.0, &mut Rng::new(3)).unwrap();
        let mut max = 0.0f32;
        for i in 0..2000 {
            let a = c.angle(i as f32 * 0.37, i as f32 * 0.91);
            max = max.max(a.abs());
        }
        assert!(
            max <= 20f32.to_radians() + 1e-6 && max > 15f32.to_radians(),
            "{max}"
        );
        assert!(Curl::new(&Texture::default(), 1.0, &mut Rng::new(3)).is_none());
    }
}
