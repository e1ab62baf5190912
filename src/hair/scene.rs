//! The hair scene: strands with per-vertex attributes, the head they grow on, the photo's
//! camera, the photo and its hair mask. One type and one folder layout for every pipeline:
//! modelling produces it, rendering reads it, simulation and editing change it.
//!
//! Folder layout: `strands.hair` (model space), `model.json` (camera, head parameters, size
//! and whatever the producing pipeline records), `photo.png`, `mask.png`, and for an edited
//! model `rest.hair` (where the photo saw the strands; `model.json` key `rest`).

use crate::error::{Error, Result};
use crate::hair::head::{Head, HeadParams, WeakPerspective};
use crate::hair::strands::StrandSet;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// A hair scene: what a model folder holds (`coif model`, `coif import`, and the edits and
/// simulations that change them) and what the renderer draws.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The folder it was loaded from or will be saved to; names files in messages.
    pub dir: PathBuf,
    /// Model space: metres, y up, the face toward +z (or the file's units when imported).
    pub strands: StrandSet,
    /// The camera of the photo; None for imported strands (a framing camera is made).
    pub camera: Option<WeakPerspective>,
    pub head: Option<Head>,
    /// The photo (sRGB 8-bit) and the hair mask (nonzero = hair), same size.
    pub photo: Option<image::RgbImage>,
    pub mask: Option<Vec<u8>>,
    pub width: u32,
    pub height: u32,
    /// A simulated or edited sequence: per-frame strand files and head poses.
    pub animation: Option<Animation>,
    /// Where the photo saw `strands`, when they have changed since (an edited model): the
    /// same counts, each vertex at its place in the model the photo was modelled into. The
    /// renderer takes the photo's colour there and draws over the photo with its hair
    /// inpainted. None: the strands are where the photo saw them.
    pub rest: Option<StrandSet>,
}

/// Frames of a scene that moves (`model.json` key `animation`): `frames/NNNN.hair` in model
/// space with the head at its pose, one pose per frame.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Animation {
    pub fps: f32,
    /// Strand files relative to the scene folder, one per frame.
    pub frames: Vec<String>,
    /// Head pose per frame: yaw, pitch, roll (degrees) and translation (metres), as
    /// `crate::sim::HeadTrack` keys them.
    pub head: Vec<[f32; 6]>,
    /// Footage per frame, for a scene tracked through a video (`coif video`): the frame's
    /// photo, hair mask (files relative to the scene folder) and the camera that sees the
    /// frame's strands in it. Absent for simulations, which play over the scene's photo.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub footage: Option<Footage>,
}

/// Per-frame photos, masks and cameras of a tracked video (see [`Animation::footage`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Footage {
    pub photos: Vec<String>,
    pub masks: Vec<String>,
    pub cameras: Vec<WeakPerspective>,
}

fn bad(path: &Path, msg: impl Into<String>) -> Error {
    Error::bad_file(path, msg)
}

/// What `model.json` says, checked: everything [`Scene::load`] takes from it. Parsed on its
/// own so that the format can be fuzzed without files.
#[derive(Clone, Debug)]
pub struct SceneMeta {
    pub camera: Option<WeakPerspective>,
    pub head: Option<Head>,
    /// The photo's size (0 when not recorded).
    pub width: u32,
    pub height: u32,
    /// The photo's path as recorded, used when the folder has no `photo.png`.
    pub image: Option<PathBuf>,
    pub animation: Option<Animation>,
    /// `rest.hair` holds where the photo saw the strands (key `rest`).
    pub rest: bool,
}

/// The file of [`Scene::rest`] in a model folder.
pub const REST_FILE: &str = "rest.hair";

impl SceneMeta {
    /// Parses `model.json` text; `meta_path` names the file in errors.
    pub fn parse(text: &str, meta_path: &Path) -> Result<SceneMeta> {
        let meta: serde_json::Value = serde_json::from_str(text)
            .map_err(|e| bad(meta_path, format!("not valid JSON: {e}")))?;
        let camera = match meta.get("camera") {
            None | Some(serde_json::Value::Null) => None,
            Some(c) => Some(
                serde_json::from_value::<WeakPerspective>(c.clone())
                    .map_err(|e| bad(meta_path, format!("camera: {e}")))?,
            ),
        };
        let head = match meta.pointer("/head/params") {
            None | Some(serde_json::Value::Null) => None,
            Some(h) => {
                let hp: HeadParams = serde_json::from_value(h.clone())
                    .map_err(|e| bad(meta_path, format!("head parameters: {e}")))?;
                Some(Head::try_new(&hp).map_err(|e| bad(meta_path, e.to_string()))?)
            }
        };
        let dim = |k: &str| meta.get(k).and_then(|v| v.as_u64()).map(|v| v as u32);
        let image = meta
            .get("image")
            .and_then(|v| v.as_str())
            .map(PathBuf::from);
        let animation = match meta.get("animation") {
            None | Some(serde_json::Value::Null) => None,
            Some(a) => {
                let a: Animation = serde_json::from_value(a.clone())
                    .map_err(|e| bad(meta_path, format!("animation: {e}")))?;
                let footage_ok = a.footage.as_ref().is_none_or(|f| {
                    [f.photos.len(), f.masks.len(), f.cameras.len()]
                        .iter()
                        .all(|&n| n == a.frames.len())
                });
                if a.frames.is_empty()
                    || a.head.len() != a.frames.len()
                    || a.fps.is_nan()
                    || a.fps <= 0.0
                    || !footage_ok
                {
                    return Err(bad(
                        meta_path,
                        format!(
                            "animation: {} frames, {} head poses, fps {}{}",
                            a.frames.len(),
                            a.head.len(),
                            a.fps,
                            a.footage.as_ref().map_or(String::new(), |f| format!(
                                ", footage of {} photos, {} masks, {} cameras",
                                f.photos.len(),
                                f.masks.len(),
                                f.cameras.len()
                            ))
                        ),
                    ));
                }
                Some(a)
            }
        };
        let rest = match meta.get("rest") {
            None | Some(Value::Null) => false,
            Some(Value::String(f)) if f == REST_FILE => true,
            Some(v) => {
                return Err(bad(
                    meta_path,
                    format!("rest: expected \"{REST_FILE}\", got {v}"),
                ))
            }
        };
        Ok(SceneMeta {
            camera,
            head,
            width: dim("width").unwrap_or(0),
            height: dim("height").unwrap_or(0),
            image,
            animation,
            rest,
        })
    }
}

impl Scene {
    /// The files and folders of a model folder that [`Scene::load`] reads: an output there
    /// would overwrite the model (a picture beside them is fine).
    pub fn inputs(dir: &Path) -> Vec<PathBuf> {
        let files = [
            "model.json",
            "strands.hair",
            "photo.png",
            "mask.png",
            REST_FILE,
        ];
        // Folders of a moving scene: its strands per frame, a tracked video's footage.
        let folders = ["frames", "photos", "masks"];
        files.iter().chain(&folders).map(|f| dir.join(f)).collect()
    }

    /// Reads `model.json`, `strands.hair` and, when present, the photo (`photo.png`, else the
    /// `image` path in `model.json`) and the hair mask (`mask.png`).
    pub fn load(dir: &Path) -> Result<Scene> {
        let meta_path = dir.join("model.json");
        let text = std::fs::read_to_string(&meta_path).map_err(|e| Error::Io {
            path: meta_path.clone(),
            err: e,
        })?;
        let SceneMeta {
            camera,
            head,
            mut width,
            mut height,
            image,
            animation,
            rest,
        } = SceneMeta::parse(&text, &meta_path)?;
        let strands_path = dir.join("strands.hair");
        let strands = crate::io::strands::read(&strands_path)?;
        check_strands(&strands, &strands_path)?;
        let rest = match rest {
            false => None,
            true => {
                let path = dir.join(REST_FILE);
                let r = crate::io::strands::read(&path)?;
                check_strands(&r, &path)?;
                if r.counts != strands.counts {
                    return Err(bad(
                        &path,
                        format!(
                            "{} strands, {} vertices, but strands.hair has {} strands, {} \
                             vertices: the rest strands must match them one to one",
                            r.counts.len(),
                            r.points.len(),
                            strands.counts.len(),
                            strands.points.len()
                        ),
                    ));
                }
                Some(r)
            }
        };
        let photo_path = [Some(dir.join("photo.png")), image]
            .into_iter()
            .flatten()
            .find(|p| p.is_file());
        let photo = match (&camera, photo_path) {
            (Some(_), Some(p)) => {
                let img = crate::io::images::load_rgb(&p)?;
                if (width, height) != (0, 0) && img.dimensions() != (width, height) {
                    return Err(bad(
                        &p,
                        format!(
                            "the photo is {}x{} but the model was made on {width}x{height}",
                            img.width(),
                            img.height()
                        ),
                    ));
                }
                (width, height) = img.dimensions();
                Some(img)
            }
            _ => None,
        };
        let mask_path = dir.join("mask.png");
        let mask = match (&photo, mask_path.is_file()) {
            (Some(ph), true) => Some(crate::io::images::load_mask(
                &mask_path,
                ph.width(),
                ph.height(),
                &mask_path,
            )?),
            _ => None,
        };
        Ok(Scene {
            dir: dir.to_path_buf(),
            strands,
            camera,
            head,
            photo,
            mask,
            width,
            height,
            animation,
            rest,
        })
    }
}

impl Scene {
    /// Strands alone (imported files): rendered with a framing camera, strands only.
    pub fn from_strands(strands: StrandSet, dir: &Path) -> Result<Scene> {
        check_strands(&strands, &dir.join("strands.hair"))?;
        Ok(Scene {
            dir: dir.to_path_buf(),
            strands,
            camera: None,
            head: None,
            photo: None,
            mask: None,
            width: 0,
            height: 0,
            animation: None,
            rest: None,
        })
    }
}

/// Non-finite points or colours make a file nothing sensible can be drawn from.
fn check_strands(s: &StrandSet, path: &Path) -> Result<()> {
    if s.points.is_empty() {
        return Err(bad(path, "the model has no strand vertex to draw"));
    }
    if let Some(i) = s
        .points
        .iter()
        .position(|p| !p.iter().all(|v| v.is_finite()))
    {
        return Err(bad(
            path,
            format!("vertex {i} is not finite: {:?}", s.points[i]),
        ));
    }
    if let Some(c) = &s.colors {
        if let Some(i) = c.iter().position(|p| !p.iter().all(|v| v.is_finite())) {
            return Err(bad(
                path,
                format!("vertex {i} has a colour that is not finite: {:?}", c[i]),
            ));
        }
    }
    if let Some(t) = &s.transparency {
        if let Some(i) = t.iter().position(|v| !v.is_finite()) {
            return Err(bad(
                path,
                format!("vertex {i} has a transparency that is not finite"),
            ));
        }
    }
    Ok(())
}

impl Scene {
    /// The strands of animation frame `k` (model space, head at that frame's pose).
    pub fn frame(&self, k: usize) -> Result<StrandSet> {
        let a = self
            .animation
            .as_ref()
            .ok_or_else(|| bad(&self.dir.join("model.json"), "the scene has no animation"))?;
        let path = self.dir.join(&a.frames[k]);
        let mut s = crate::io::strands::read(&path)?;
        check_strands(&s, &path)?;
        // Frames carry positions; the attributes are the scene's when the strands match.
        if s.counts == self.strands.counts {
            s.colors = s.colors.or_else(|| self.strands.colors.clone());
            s.transparency = s.transparency.or_else(|| self.strands.transparency.clone());
            s.thickness = s.thickness.or_else(|| self.strands.thickness.clone());
        }
        Ok(s)
    }

    /// Frame `k` of a tracked video as a still scene: the frame's strands, photo, hair mask
    /// and camera. None when the animation has no footage.
    pub fn footage_frame(&self, k: usize) -> Result<Option<Scene>> {
        let Some(f) = self.animation.as_ref().and_then(|a| a.footage.as_ref()) else {
            return Ok(None);
        };
        let photo_path = self.dir.join(&f.photos[k]);
        let photo = crate::io::images::load_rgb(&photo_path)?;
        let (w, h) = photo.dimensions();
        let mask_path = self.dir.join(&f.masks[k]);
        let mask = crate::io::images::load_mask(&mask_path, w, h, &photo_path)?;
        // Field by field rather than a clone of `self`: the reference's strands, photo and
        // animation would be copied only to be replaced (a model's strands are tens of MB).
        Ok(Some(Scene {
            dir: self.dir.clone(),
            strands: self.frame(k)?,
            camera: Some(f.cameras[k]),
            head: self.head.clone(),
            photo: Some(photo),
            mask: Some(mask),
            width: w,
            height: h,
            animation: None,
            rest: None,
        }))
    }

    /// Writes the scene to `dir` (created): `strands.hair`, `photo.png` and `mask.png` when
    /// present, and `model.json` with the scene's keys deep-merged with `extra` (what the
    /// producing pipeline records: parameters, figures, timings). Every file is written to a
    /// temporary name and renamed, so a failure leaves earlier files whole.
    pub fn save(&self, dir: &Path, extra: Value) -> Result<()> {
        crate::io::ensure_dir(dir)?;
        crate::io::strands::write(&dir.join("strands.hair"), &self.strands)?;
        if let Some(rest) = &self.rest {
            crate::io::strands::write(&dir.join(REST_FILE), rest)?;
        }
        // The photo travels with the model, so `coif render` needs nothing else.
        if let Some(photo) = &self.photo {
            crate::io::write_png(&dir.join("photo.png"), photo)?;
        }
        if let Some(mask) = &self.mask {
            let img = image::GrayImage::from_fn(self.width, self.height, |x, y| {
                let on = mask[(y * self.width + x) as usize] != 0;
                image::Luma([if on { 255 } else { 0 }])
            });
            crate::io::write_png(&dir.join("mask.png"), &img)?;
        }
        let mut meta = json!({
            "version": 1,
            "coif": env!("CARGO_PKG_VERSION"),
            "strands": { "final": self.strands.len(), "vertices": self.strands.points.len() },
        });
        if let Some(cam) = &self.camera {
            merge(
                &mut meta,
                json!({
                    "width": self.width,
                    "height": self.height,
                    "units": "model space in metres, y up, the face looks toward +z",
                    "image_from_model": cam.image_from_model(),
                    "image_from_model_doc": "rows map homogeneous model points (x, y, z, 1) to image x (px, right), image y (px, down) and depth (px, toward the camera)",
                    "camera": cam,
                }),
            );
        } else {
            let (lo, hi) = self.strands.bounds();
            merge(
                &mut meta,
                json!({ "bounds": [lo, hi], "image_from_model": Value::Null }),
            );
        }
        if let Some(head) = &self.head {
            merge(&mut meta, json!({ "head": { "params": head.params() } }));
        }
        if let Some(a) = &self.animation {
            merge(&mut meta, json!({ "animation": a }));
        }
        if self.rest.is_some() {
            merge(&mut meta, json!({ "rest": REST_FILE }));
        }
        merge(&mut meta, extra);
        let text = serde_json::to_string_pretty(&meta)
            .map_err(|e| Error::Invalid(format!("model.json: {e}")))?;
        crate::io::write_atomic(&dir.join("model.json"), text.as_bytes())
    }
}

/// Merges `b` into `a`: objects key by key, recursively; anything else replaces.
fn merge(a: &mut Value, b: Value) {
    match (a, b) {
        (Value::Object(a), Value::Object(b)) => {
            for (k, v) in b {
                match a.get_mut(&k) {
                    Some(slot) => merge(slot, v),
                    None => {
                        a.insert(k, v);
                    }
                }
            }
        }
        (a, b) => *a = b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merge_is_deep_and_b_wins() {
        let mut a = json!({"head": {"params": 1}, "x": 1, "keep": true});
        merge(&mut a, json!({"head": {"fit": 2}, "x": {"y": 3}}));
        assert_eq!(
            a,
            json!({"head": {"params": 1, "fit": 2}, "x": {"y": 3}, "keep": true})
        );
    }
}
