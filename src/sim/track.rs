//! The head's rigid motion over a simulation: keyframed yaw, pitch, roll (degrees, the
//! render's conventions: yaw about +y turns the face toward image right, pitch about −x
//! lifts it, roll about +z) and translation (metres), eased between keys with a smoothstep
//! so the head starts and stops without a jolt. Rotations are about the model origin (the
//! head centre).

use crate::error::{Error, Result};
use glam::{Mat3, Vec3};
use serde::Serialize;

/// One key of one channel: (frame, value).
pub type HeadKey = (f32, f32);

/// Keys per channel; an empty channel stays at 0.
#[derive(Clone, Debug, Default, Serialize)]
pub struct HeadTrack {
    pub yaw: Vec<HeadKey>,
    pub pitch: Vec<HeadKey>,
    pub roll: Vec<HeadKey>,
    pub tx: Vec<HeadKey>,
    pub ty: Vec<HeadKey>,
    pub tz: Vec<HeadKey>,
}

/// Rotation (rows) and translation.
pub type Rigid = (Mat3, Vec3);

/// Parses "frame:value,frame:value,..." (frames ascending), e.g. "0:0,45:20,90:0".
pub fn parse_keys(s: &str) -> std::result::Result<Vec<HeadKey>, String> {
    let mut keys = Vec::new();
    for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let (f, v) = part
            .split_once(':')
            .ok_or_else(|| format!("expected frame:value, got {part:?} in {s:?}"))?;
        let f: f32 = f
            .trim()
            .parse()
            .map_err(|_| format!("frame {f:?} in {s:?} is not a number"))?;
        let v: f32 = v
            .trim()
            .parse()
            .map_err(|_| format!("value {v:?} in {s:?} is not a number"))?;
        if !f.is_finite() || !v.is_finite() || f < 0.0 {
            return Err(format!(
                "{part:?} in {s:?}: frames must be finite and ≥ 0, values finite"
            ));
        }
        if keys.last().is_some_and(|&(last, _)| f <= last) {
            return Err(format!("frames must increase in {s:?}"));
        }
        keys.push((f, v));
    }
    if keys.is_empty() {
        return Err(format!("no keys in {s:?}"));
    }
    Ok(keys)
}

fn smoothstep(t: f32) -> f32 {
    t * t * (3.0 - 2.0 * t)
}

/// The channel's value at `frame`: held before the first and after the last key.
fn eval(keys: &[HeadKey], frame: f32) -> f32 {
    let Some(&(f0, v0)) = keys.first() else {
        return 0.0;
    };
    if frame <= f0 {
        return v0;
    }
    for w in keys.windows(2) {
        let ((fa, va), (fb, vb)) = (w[0], w[1]);
        if frame <= fb {
            return va + (vb - va) * smoothstep((frame - fa) / (fb - fa));
        }
    }
    keys[keys.len() - 1].1
}

/// Largest rate of a channel (value per frame): smoothstep peaks at 1.5x the mean slope.
fn max_rate(keys: &[HeadKey]) -> f32 {
    keys.windows(2)
        .map(|w| 1.5 * (w[1].1 - w[0].1).abs() / (w[1].0 - w[0].0))
        .fold(0.0, f32::max)
}

impl HeadTrack {
    pub fn is_still(&self) -> bool {
        [
            &self.yaw,
            &self.pitch,
            &self.roll,
            &self.tx,
            &self.ty,
            &self.tz,
        ]
        .iter()
        .all(|k| k.iter().all(|&(_, v)| v == k[0].1))
    }

    /// Yaw, pitch, roll (degrees) and translation (metres) at `frame`.
    pub fn pose(&self, frame: f32) -> [f32; 6] {
        [
            eval(&self.yaw, frame),
            eval(&self.pitch, frame),
            eval(&self.roll, frame),
            eval(&self.tx, frame),
            eval(&self.ty, frame),
            eval(&self.tz, frame),
        ]
    }

    /// The head transform at `frame` (fractional frames between keys).
    pub fn transform(&self, frame: f32) -> Rigid {
        pose_transform(&self.pose(frame))
    }

    /// A bound on the speed of a point within 0.5 m of the head centre (m/s).
    pub fn max_speed(&self, fps: f32) -> f32 {
        let ang = [&self.yaw, &self.pitch, &self.roll]
            .iter()
            .map(|k| max_rate(k).to_radians())
            .sum::<f32>();
        let lin = [&self.tx, &self.ty, &self.tz]
            .iter()
            .map(|k| max_rate(k))
            .sum::<f32>();
        (0.5 * ang + lin) * fps
    }

    pub fn validate(&self) -> Result<()> {
        for (name, k) in [
            ("yaw", &self.yaw),
            ("pitch", &self.pitch),
            ("roll", &self.roll),
            ("tx", &self.tx),
            ("ty", &self.ty),
            ("tz", &self.tz),
        ] {
            if k.iter().any(|(f, v)| !f.is_finite() || !v.is_finite()) {
                return Err(Error::Invalid(format!("head {name}: keys must be finite")));
            }
            if k.windows(2).any(|w| w[1].0 <= w[0].0) {
                return Err(Error::Invalid(format!("head {name}: frames must increase")));
            }
        }
        Ok(())
    }
}

/// The rigid transform of a pose (yaw, pitch, roll in degrees; translation).
pub fn pose_transform(p: &[f32; 6]) -> Rigid {
    let r = Mat3::from_rotation_y(p[0].to_radians())
        * Mat3::from_rotation_x(-p[1].to_radians())
        * Mat3::from_rotation_z(p[2].to_radians());
    (r, Vec3::new(p[3], p[4], p[5]))
}

pub fn apply(m: &Rigid, p: [f32; 3]) -> [f32; 3] {
    (m.0 * Vec3::from_array(p) + m.1).to_array()
}

pub fn apply_inv(m: &Rigid, p: [f32; 3]) -> [f32; 3] {
    (m.0.transpose() * (Vec3::from_array(p) - m.1)).to_array()
}

/// The layout of one step in the simulation's `motion` buffer: rotation rows, translation.
pub fn pack(m: &Rigid) -> [f32; 12] {
    let r = m.0.transpose(); // glam is column-major: the transpose's columns are the rows.
    [
        r.x_axis.x, r.x_axis.y, r.x_axis.z, r.y_axis.x, r.y_axis.y, r.y_axis.z, r.z_axis.x,
        r.z_axis.y, r.z_axis.z, m.1.x, m.1.y, m.1.z,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_parse_and_ease() {
        let k = parse_keys("0:0, 45:20 ,90:0").unwrap();
        assert_eq!(k, vec![(0.0, 0.0), (45.0, 20.0), (90.0, 0.0)]);
        assert_eq!(eval(&k, 45.0), 20.0);
        assert_eq!(eval(&k, 200.0), 0.0);
        assert!((eval(&k, 22.5) - 10.0).abs() < 1e-5);
        for bad in ["", "0", "a:1", "1:b", "5:0,3:1", "-1:0", "0:inf"] {
            assert!(parse_keys(bad).is_err(), "{bad:?}");
        }
    }

    #[test]
    fn pack_matches_apply() {
        let tr = HeadTrack {
            yaw: vec![(0.0, 30.0)],
            pitch: vec![(0.0, -10.0)],
            tx: vec![(0.0, 0.01)],
            ..Default::default()
        };
        let m = tr.transform(0.0);
        let p = [0.1, -0.05, 0.2];
        let q = apply(&m, p);
        let k = pack(&m);
        for r in 0..3 {
            let v = k[3 * r] * p[0] + k[3 * r + 1] * p[1] + k[3 * r + 2] * p[2] + k[9 + r];
            assert!((v - q[r]).abs() < 1e-6);
        }
        let back = apply_inv(&m, q);
        assert!((0..3).all(|c| (back[c] - p[c]).abs() < 1e-6));
    }
}
