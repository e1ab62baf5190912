//! The head mesh with a face texture for novel views (C13 §4: "a 3D head model with an
//! automatically inpainted texture as in [Chai et al. 2012]").
//!
//! * **UV map**: spherical about a centre `c` on the head's vertical axis (the skull centre's
//!   x and z, the face centre's height, so the face sits on the equator where the map is
//!   least distorted): `u = 0.5 + atan2(x, z) / 2π` (the face, +z, at u = 0.5, the model's +x
//!   side, image right in a frontal view, at u = 0.75, so the texture reads like the photo),
//!   `v = acos(y / |p|) / π` (0 at the crown). The seam u = 0 ≡ 1 runs down the back of the
//!   head. Triangles crossing it are clipped on it, and the new vertices on the seam exist
//!   twice (u = 1 on one side, u = 0 on the other, the same position), so no triangle
//!   straddles it and the renderer never interpolates u across the wrap. The texture is
//!   `tex_size` x `tex_size / 2` texels, so a texel spans the same angle both ways at the
//!   equator.
//! * **Texel convention**: texel (i, j) has its centre at uv ((i + 0.5) / W, (j + 0.5) / H),
//!   row j = 0 at v = 0 (the crown), as the renderer's bilinear sampler expects; the colour
//!   stored for a texel is the surface's at exactly that uv.
//! * **Projection**: each texel centre is located on the mesh by rasterising the triangles in
//!   uv space (barycentric position and normal); the point takes the photo's colour (bilinear,
//!   pixel centres at i + 0.5) when it faces the camera (normal · view ≥ `min_facing`), is the
//!   front-most surface there (the head's own depth map, from coif's depth rasteriser, so the
//!   nose or an ear hides what is behind it) and all four photo taps are `usable`.
//! * **Mirror**: a texel the photo did not show takes the colour of its mirror image across
//!   the face's symmetry plane (u ↔ 1 − u) when the photo showed that one, so a face side
//!   hidden by hair or turned away continues the other side's skin and features.
//! * **Fill**: texels within `near_band` of the photo texels (hidden by hair: forehead,
//!   temples, ears, the sides of the neck) are inpainted by PatchMatch in texture space, so
//!   skin texture continues into them. The far back of the head gets a smooth push-pull fill
//!   (periodic in u) instead: it is never seen in the photo, PatchMatch would plant copies of
//!   eyes or lips there, and a smooth skin tone is the safer guess for a part that is
//!   normally under the hair anyway; the far fill is also cheaper.

use crate::error::{Error, Result};
use crate::gpu::engine::Engine;
use crate::hair::head::{Head, WeakPerspective};
use crate::model::volume::{rasterize_depth, Mesh};
use crate::render::inpaint::{inpaint, push_pull, InpaintParams, InpaintReport};
use glam::{DVec3, Vec3};
use std::collections::HashMap;

/// A texel copied from the photo.
pub const TEXEL_PHOTO: u8 = 1;
/// A texel filled by PatchMatch (near the photo texels).
pub const TEXEL_PATCHMATCH: u8 = 2;
/// A texel filled by the smooth push-pull fill (the far back).
pub const TEXEL_SMOOTH: u8 = 3;
/// A texel the photo did not show, copied from its mirror image across the face's
/// symmetry plane (u ↔ 1 − u), which the photo did show.
pub const TEXEL_MIRROR: u8 = 4;

/// Tuning of [`head_texture_with`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct HeadTextureParams {
    /// Texture width in texels (height is half of it).
    pub tex_size: u32,
    /// `Head::mesh` resolution.
    pub mesh_res: u32,
    /// Smallest cosine between the surface normal and the direction to the camera for a
    /// photo texel: grazing surfaces smear a pixel over many texels.
    pub min_facing: f32,
    /// Depth slack (px) for the self-occlusion test, on top of the surface slope.
    pub depth_tolerance: f32,
    /// Width of the PatchMatch band around the photo texels, as a share of the texture
    /// height; texels further away get the smooth fill.
    pub near_band: f32,
    pub inpaint: InpaintParams,
}

impl Default for HeadTextureParams {
    fn default() -> Self {
        HeadTextureParams {
            tex_size: 512,
            mesh_res: 96,
            min_facing: 0.2,
            depth_tolerance: 1.0,
            near_band: 0.125,
            inpaint: InpaintParams::default(),
        }
    }
}

/// Figures of a [`head_texture_with`] run.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HeadTextureReport {
    /// Texels whose centre lies on a mesh triangle in uv space.
    pub mapped_texels: usize,
    pub photo_texels: usize,
    pub patchmatch_texels: usize,
    pub smooth_texels: usize,
    pub mirror_texels: usize,
    /// Triangles clipped on the uv seam.
    pub seam_triangles: usize,
    pub inpaint: Option<InpaintReport>,
}

/// A head mesh (model space) with uvs and its texture.
#[derive(Clone, Debug)]
pub struct TexturedHead {
    pub positions: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    /// Counter-clockwise seen from outside, as `Head::mesh`.
    pub triangles: Vec<[u32; 3]>,
    /// (width, height, linear RGBA with alpha 1), row 0 at v = 0; texel centres at
    /// ((i + 0.5) / width, (j + 0.5) / height).
    pub texture: (u32, u32, Vec<[f32; 4]>),
    /// Where each texel's colour came from: [`TEXEL_PHOTO`], [`TEXEL_MIRROR`],
    /// [`TEXEL_PATCHMATCH`] or [`TEXEL_SMOOTH`].
    pub texel_source: Vec<u8>,
    /// The surface point each texel centre shows (None where no triangle maps it), for
    /// layers that decide per texel what the photo shows there.
    pub surface: Vec<Option<Texel>>,
    pub report: HeadTextureReport,
}

/// Centre of the spherical uv map (see the module notes).
pub fn uv_centre(head: &Head) -> Vec3 {
    let p = head.params();
    Vec3::new(p.skull_centre[0], p.face_centre[1], p.skull_centre[2])
}

/// Spherical uv of a model-space point about `centre`, u in [0, 1] with the seam at the back.
pub fn sphere_uv(p: Vec3, centre: Vec3) -> [f32; 2] {
    let d = (p - centre).as_dvec3();
    let u = 0.5 + d.x.atan2(d.z) / std::f64::consts::TAU;
    let len = d.length().max(1e-12);
    let v = (d.y / len).clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
    [u.clamp(0.0, 1.0) as f32, v.clamp(0.0, 1.0) as f32]
}

/// A corner of a clipped polygon: an original vertex or a point on a mesh edge (a < b).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
enum Corner {
    Vert(u32),
    Edge(u32, u32),
}

/// A mesh with uvs, cut along the seam.
#[derive(Clone, Debug)]
pub struct UvMesh {
    pub positions: Vec<[f32; 3]>,
    pub uvs: Vec<[f32; 2]>,
    pub triangles: Vec<[u32; 3]>,
    /// Input triangles that crossed the seam and were clipped on it.
    pub seam_triangles: usize,
}

/// The uv mesh of `positions` / `triangles` about `centre` (see the module notes).
pub fn uv_mesh(positions: &[Vec3], triangles: &[[u32; 3]], centre: Vec3) -> UvMesh {
    let uv0: Vec<[f32; 2]> = positions.iter().map(|&p| sphere_uv(p, centre)).collect();
    let mut pos: Vec<[f32; 3]> = positions.iter().map(|p| p.to_array()).collect();
    let mut uvs = uv0.clone();
    let mut tris = Vec::with_capacity(triangles.len() + 64);
    // Extra vertices: (corner, side) -> index; side 0 is u' <= 1 (uv u = u'), side 1 is
    // u' >= 1 (uv u = u' - 1).
    let mut extra: HashMap<(Corner, u8), u32> = HashMap::new();
    let mut clipped = 0;
    for t in triangles {
        let u = t.map(|i| uv0[i as usize][0]);
        let (lo, hi) = (
            u.iter().copied().fold(1.0, f32::min),
            u.iter().copied().fold(0.0, f32::max),
        );
        if hi - lo <= 0.5 {
            tris.push(*t);
            continue;
        }
        clipped += 1;
        // Unwrapped coordinate: vertices on the far (small-u) side move to u + 1.
        let uw = |i: u32| {
            let uu = uv0[i as usize][0];
            if uu < 0.5 {
                uu + 1.0
            } else {
                uu
            }
        };
        // Corner -> (v, position); an edge corner is where u' = 1 on it.
        let corner_at = |c: Corner| -> (f32, Vec3) {
            match c {
                Corner::Vert(i) => (uv0[i as usize][1], positions[i as usize]),
                Corner::Edge(a, b) => {
                    let (ua, ub) = (uw(a), uw(b));
                    let s = (1.0 - ua) / (ub - ua);
                    let v = uv0[a as usize][1] + s * (uv0[b as usize][1] - uv0[a as usize][1]);
                    (v, positions[a as usize].lerp(positions[b as usize], s))
                }
            }
        };
        for side in 0..2u8 {
            // Sutherland-Hodgman against u' <= 1 (side 0) or u' >= 1 (side 1).
            let inside = |uu: f32| if side == 0 { uu <= 1.0 } else { uu >= 1.0 };
            let mut poly: Vec<Corner> = Vec::with_capacity(4);
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                let (ia, ib) = (inside(uw(a)), inside(uw(b)));
                if ia {
                    poly.push(Corner::Vert(a));
                }
                if ia != ib && uw(a) != 1.0 && uw(b) != 1.0 {
                    poly.push(Corner::Edge(a.min(b), a.max(b)));
                }
            }
            if poly.len() < 3 {
                continue;
            }
            let idx: Vec<u32> = poly
                .iter()
                .map(|&c| {
                    // The uv u this corner needs on this side; an original vertex keeps its
                    // own unless it sits on the seam and is used on the other side.
                    let want = match c {
                        Corner::Vert(i) => {
                            let uu = uv0[i as usize][0];
                            match (side, uu < 0.5) {
                                (0, false) | (1, true) => return i,
                                (0, true) => 1.0,
                                _ => 0.0,
                            }
                        }
                        Corner::Edge(..) => [1.0, 0.0][side as usize],
                    };
                    *extra.entry((c, side)).or_insert_with(|| {
                        let (v, p) = corner_at(c);
                        pos.push(p.to_array());
                        uvs.push([want, v]);
                        (pos.len() - 1) as u32
                    })
                })
                .collect();
            for k in 1..idx.len() - 1 {
                tris.push([idx[0], idx[k], idx[k + 1]]);
            }
        }
    }
    UvMesh {
        positions: pos,
        uvs,
        triangles: tris,
        seam_triangles: clipped,
    }
}

/// Texture with its mesh; see [`head_texture_with`] (default parameters but the sizes).
#[allow(clippy::too_many_arguments)]
pub fn head_texture(
    engine: &Engine,
    head: &Head,
    camera: &WeakPerspective,
    photo: &[[f32; 3]],
    width: u32,
    height: u32,
    usable: &[u8],
    tex_size: u32,
    mesh_res: u32,
) -> Result<TexturedHead> {
    let p = HeadTextureParams {
        tex_size,
        mesh_res,
        ..Default::default()
    };
    head_texture_with(engine, head, camera, photo, width, height, usable, &p)
}

/// What a texel centre sees of the mesh.
#[derive(Clone, Copy, Debug)]
pub struct Texel {
    /// The surface point (model space).
    pub pos: Vec3,
    /// Its outward unit normal.
    pub normal: Vec3,
    /// Distance from the uv centre: where uv triangles overlap (the map is not one-to-one
    /// around the ears and under the chin), the outermost surface wins.
    reach: f32,
}

/// Textures `head` from `photo` (linear RGB, `width` x `height`) seen by `camera`, using only
/// the pixels where `usable` is nonzero (skin, face, ears, neck: not hair, not background).
#[allow(clippy::too_many_arguments)]
pub fn head_texture_with(
    engine: &Engine,
    head: &Head,
    camera: &WeakPerspective,
    photo: &[[f32; 3]],
    width: u32,
    height: u32,
    usable: &[u8],
    p: &HeadTextureParams,
) -> Result<TexturedHead> {
    camera.validate()?;
    let n_px = width as u64 * height as u64;
    if n_px == 0 || photo.len() as u64 != n_px || usable.len() as u64 != n_px {
        return Err(Error::Invalid(format!(
            "head texture: a {width}x{height} photo needs {n_px} pixels and {n_px} usable-mask \
             bytes, got {} and {}",
            photo.len(),
            usable.len()
        )));
    }
    if !(8..=8192).contains(&p.tex_size) {
        return Err(Error::Invalid(format!(
            "head texture: tex_size must be in 8..=8192, got {}",
            p.tex_size
        )));
    }
    if !(p.min_facing.is_finite() && p.depth_tolerance.is_finite() && p.near_band.is_finite()) {
        return Err(Error::Invalid(
            "head texture: min_facing, depth_tolerance and near_band must be finite".into(),
        ));
    }
    let (tw, th) = (p.tex_size, (p.tex_size / 2).max(4));
    let (mesh_pos, mesh_tris) = head.mesh(p.mesh_res);
    let centre = uv_centre(head);
    let UvMesh {
        positions,
        uvs,
        triangles,
        seam_triangles,
    } = uv_mesh(&mesh_pos, &mesh_tris, centre);
    let normals: Vec<Vec3> = positions
        .iter()
        .map(|&q| head.sdf_grad(Vec3::from(q)))
        .collect();

    // 1. Texel centres on the mesh: rasterise the triangles in uv space.
    let n_tex = (tw * th) as usize;
    let mut texels: Vec<Option<Texel>> = vec![None; n_tex];
    for t in &triangles {
        let uv = t.map(|i| {
            let q = uvs[i as usize];
            // Texel-index space: texel (i, j) centre at (i + 0.5, j + 0.5).
            [q[0] as f64 * tw as f64, q[1] as f64 * th as f64]
        });
        let area = (uv[1][0] - uv[0][0]) * (uv[2][1] - uv[0][1])
            - (uv[2][0] - uv[0][0]) * (uv[1][1] - uv[0][1]);
        if area.abs() < 1e-14 {
            continue;
        }
        let lo_x = uv.iter().map(|q| q[0]).fold(f64::INFINITY, f64::min);
        let hi_x = uv.iter().map(|q| q[0]).fold(f64::NEG_INFINITY, f64::max);
        let lo_y = uv.iter().map(|q| q[1]).fold(f64::INFINITY, f64::min);
        let hi_y = uv.iter().map(|q| q[1]).fold(f64::NEG_INFINITY, f64::max);
        let (i0, i1) = (
            (lo_x - 0.5).ceil().max(0.0) as i64,
            (hi_x - 0.5).floor().min(tw as f64 - 1.0) as i64,
        );
        let (j0, j1) = (
            (lo_y - 0.5).ceil().max(0.0) as i64,
            (hi_y - 0.5).floor().min(th as f64 - 1.0) as i64,
        );
        for j in j0..=j1 {
            for i in i0..=i1 {
                let (x, y) = (i as f64 + 0.5, j as f64 + 0.5);
                let e = |a: [f64; 2], b: [f64; 2]| {
                    (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0])
                };
                let l0 = e(uv[1], uv[2]) / area;
                let l1 = e(uv[2], uv[0]) / area;
                let l2 = e(uv[0], uv[1]) / area;
                const EPS: f64 = -1e-9;
                if l0 < EPS || l1 < EPS || l2 < EPS {
                    continue;
                }
                let at = |f: &dyn Fn(u32) -> DVec3| f(t[0]) * l0 + f(t[1]) * l1 + f(t[2]) * l2;
                let q = at(&|k| Vec3::from(positions[k as usize]).as_dvec3()).as_vec3();
                let nrm = at(&|k| normals[k as usize].as_dvec3())
                    .normalize_or_zero()
                    .as_vec3();
                let reach = (q - centre).length();
                let k = (j as u32 * tw + i as u32) as usize;
                if texels[k].is_none_or(|old| reach > old.reach) {
                    texels[k] = Some(Texel {
                        pos: q,
                        normal: nrm,
                        reach,
                    });
                }
            }
        }
    }

    // 2. The head's own front depth, for self-occlusion.
    let proj: Vec<[f32; 3]> = positions
        .iter()
        .map(|&q| camera.project(Vec3::from(q)).to_array())
        .collect();
    let mesh = Mesh {
        verts: proj,
        tris: triangles.clone(),
    };
    let depth = rasterize_depth(engine, width, height, &[&mesh])?;

    // 3. Photo texels.
    let toward_cam = camera.r.row(2);
    let mut tex = vec![[0.0f32; 3]; n_tex];
    let mut source = vec![0u8; n_tex];
    let (w, h) = (width as i64, height as i64);
    for (k, t) in texels.iter().enumerate() {
        let Some(t) = t else { continue };
        let c = t.normal.dot(toward_cam);
        if c < p.min_facing.max(1e-3) {
            continue;
        }
        let q = camera.project(t.pos);
        let (pxi, pyi) = (q.x.floor() as i64, q.y.floor() as i64);
        if pxi < 0 || pyi < 0 || pxi >= w || pyi >= h {
            continue;
        }
        let front = depth.front[(pyi * w + pxi) as usize];
        let slope = (1.0 - c * c).max(0.0).sqrt() / c;
        // Hidden behind the front surface; an uncovered pixel (front = -inf) hides nothing.
        if q.z < front - (p.depth_tolerance + slope) {
            continue;
        }
        // Bilinear, pixel centres at i + 0.5; every tap must be in the photo and usable.
        let (fx, fy) = (q.x - 0.5, q.y - 0.5);
        let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
        let (ax, ay) = (fx - x0 as f32, fy - y0 as f32);
        if x0 < 0 || y0 < 0 || x0 + 1 >= w || y0 + 1 >= h {
            continue;
        }
        let taps = [
            ((y0 * w + x0) as usize, (1.0 - ax) * (1.0 - ay)),
            ((y0 * w + x0 + 1) as usize, ax * (1.0 - ay)),
            (((y0 + 1) * w + x0) as usize, (1.0 - ax) * ay),
            (((y0 + 1) * w + x0 + 1) as usize, ax * ay),
        ];
        if taps.iter().any(|&(i, _)| usable[i] == 0) {
            continue;
        }
        let mut col = [0.0f32; 3];
        for &(i, wt) in &taps {
            for (a, b) in col.iter_mut().zip(photo[i]) {
                *a += wt * b;
            }
        }
        if !col.iter().all(|v| v.is_finite()) {
            continue;
        }
        tex[k] = col;
        source[k] = TEXEL_PHOTO;
    }
    let photo_texels = source.iter().filter(|&&s| s == TEXEL_PHOTO).count();
    if photo_texels == 0 {
        return Err(Error::Invalid(
            "head texture: no part of the head faces the camera on a usable pixel (the usable \
             mask is empty over the projected head, or the camera does not see the head)"
                .into(),
        ));
    }

    // 4. Mirror: the head is symmetric about the plane x = centre.x, which the map sends to
    // u = 0.5 (and the seam), so texel column i mirrors to tw - 1 - i. A texel the photo
    // did not show (hair over one side of the face, the far side turned away) takes its
    // mirror image's photo colour: the face's other side rather than a guess.
    for j in 0..th as usize {
        for i in 0..tw as usize {
            let k = j * tw as usize + i;
            let km = j * tw as usize + (tw as usize - 1 - i);
            if texels[k].is_some() && source[k] == 0 && source[km] == TEXEL_PHOTO {
                tex[k] = tex[km];
                source[k] = TEXEL_MIRROR;
            }
        }
    }

    // 5. Fill: smooth everywhere first (periodic in u), then PatchMatch in the near band.
    let known: Vec<bool> = source
        .iter()
        .map(|&s| s == TEXEL_PHOTO || s == TEXEL_MIRROR)
        .collect();
    let smooth = push_pull(tw, th, &tex, &known, true);
    let dist = distance_wrap_x(tw, th, &known);
    let band = p.near_band * th as f32;
    let mut hole = vec![0u8; n_tex];
    for k in 0..n_tex {
        if !known[k] {
            tex[k] = smooth[k];
            if dist[k] <= band {
                hole[k] = 1;
                source[k] = TEXEL_PATCHMATCH;
            } else {
                source[k] = TEXEL_SMOOTH;
            }
        }
    }
    let mut inpaint_report = None;
    if hole.contains(&1) {
        let (filled, rep) = inpaint(engine, tw, th, &tex, &hole, &p.inpaint)?;
        tex = filled;
        inpaint_report = Some(rep);
    }
    let count = |s: u8| source.iter().filter(|&&x| x == s).count();
    let report = HeadTextureReport {
        mapped_texels: texels.iter().filter(|t| t.is_some()).count(),
        photo_texels,
        patchmatch_texels: count(TEXEL_PATCHMATCH),
        smooth_texels: count(TEXEL_SMOOTH),
        mirror_texels: count(TEXEL_MIRROR),
        seam_triangles,
        inpaint: inpaint_report,
    };
    Ok(TexturedHead {
        positions,
        uvs,
        triangles,
        texture: (
            tw,
            th,
            tex.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect(),
        ),
        texel_source: source,
        surface: texels,
        report,
    })
}

/// Euclidean-ish (chamfer 1, √2) distance in texels to the nearest `known` texel, rows
/// periodic (u wraps); infinite when nothing is known.
fn distance_wrap_x(w: u32, h: u32, known: &[bool]) -> Vec<f32> {
    let (w, h) = (w as usize, h as usize);
    let mut d: Vec<f32> = known
        .iter()
        .map(|&k| if k { 0.0 } else { f32::INFINITY })
        .collect();
    const D1: f32 = 1.0;
    const D2: f32 = std::f32::consts::SQRT_2;
    // Two sweeps each way; the wrap is closed by running every sweep twice around the row.
    for _ in 0..2 {
        for y in 0..h {
            for xx in 0..2 * w {
                let x = xx % w;
                let xl = (x + w - 1) % w;
                let i = y * w + x;
                let mut v = d[i].min(d[y * w + xl] + D1);
                if y > 0 {
                    let (a, b, c) = ((y - 1) * w + xl, (y - 1) * w + x, (y - 1) * w + (x + 1) % w);
                    v = v.min(d[a] + D2).min(d[b] + D1).min(d[c] + D2);
                }
                d[i] = v;
            }
        }
        for y in (0..h).rev() {
            for xx in (0..2 * w).rev() {
                let x = xx % w;
                let xr = (x + 1) % w;
                let i = y * w + x;
                let mut v = d[i].min(d[y * w + xr] + D1);
                if y + 1 < h {
                    let (a, b, c) = (
                        (y + 1) * w + (x + w - 1) % w,
                        (y + 1) * w + x,
                        (y + 1) * w + xr,
                    );
                    v = v.min(d[a] + D2).min(d[b] + D1).min(d[c] + D2);
                }
                d[i] = v;
            }
        }
    }
    d
}
