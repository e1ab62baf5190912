//! The layers a composite render draws under the strands: the background and the head mesh.
//!
//! * **Original view**: the background is the photo itself (recoloured inside the hair mask
//!   as the strands are), and the head mesh carries the same picture with screen-space uvs.
//!   So wherever no strand covers a hair pixel of the mask, or the fitted head hides strands
//!   the photo shows in front of it, the composite yields to the photo: every hair pixel of
//!   the mask comes back as hair, never as skin or inpainted background (issue 19).
//! * **Novel view**: the background is the photo with the hair and the face removed and
//!   inpainted (the face: the photo's skin and inner face under the fitted head above the
//!   chin, grown by the hair margin and 3 px; below the mouth and as wide as the photo's
//!   neck it takes the colour under the chin, the neck behind the jaw), the same for every
//!   novel view. The head mesh
//!   keeps what the photo shows as head, cut along the photo's pixels by its texture's
//!   alpha (coverage, anti-aliased; see `render::raster`): below the chin the photo's skin
//!   ([`skin_mask`]), so the neck ends where the photo's neck does; above it, where it faces
//!   the photo's camera, face or hair; turned away from it, the scalp only (the back of the
//!   skull, [`unseen_texel_stays`]).
//!   Clothing stays in the background, where the body stays put. The neck twists: its
//!   vertices turn with the head in proportion to their height between the lowest visible
//!   skin (not turned, so the neck stays on the photo's neck) and the chin (turned fully).
//!   The face texture is projected only from skin and from the inner face (brows, eyes,
//!   mouth), so background and clothing pixels inside the parametric outline do not smear
//!   onto the head.

use super::face_warp::FaceWarp;
use super::{rotation, RenderParams, RenderReport, ViewCamera};
use crate::base::colour;
use crate::base::mask::{dilate, erode};
use crate::error::Result;
use crate::hair::head::texture::head_texture_with;
use crate::hair::head::{Head, WeakPerspective};
use crate::hair::scene::Scene;
use crate::render::inpaint::inpaint;
use crate::render::raster::{ScreenMesh, Texture};
use crate::Engine;
use glam::{Mat3, Vec2, Vec3};

/// The layers under the strands of a composite render, at the photo's size.
pub struct Layers {
    /// Linear RGBA, alpha 1.
    pub background: Vec<[f32; 4]>,
    /// Photo pixels the background fills by inpainting (none at the original view).
    pub hole: Vec<u8>,
    /// The photo's skin region ([`skin_mask`]; all zero without a head or at the original view).
    pub skin: Vec<u8>,
    /// The head mesh as the view sees it.
    pub mesh: Option<ScreenMesh>,
}

/// The layers of a render of `m` with `p` (what [`crate::render::render`] draws the strands
/// over), for checks of what a view may change.
pub fn render_layers(engine: &Engine, m: &Scene, p: &RenderParams) -> Result<Layers> {
    let vc = super::view_camera(m, p)?;
    let photo = m.photo.as_ref().ok_or_else(|| {
        crate::error::Error::Invalid(format!("{} has no photo to render into", m.dir.display()))
    })?;
    let lin = super::linear_photo(photo);
    layers(
        engine,
        m,
        &lin,
        &vc,
        p,
        false,
        &mut RenderReport::default(),
        None,
    )
}

/// The background layer and the head mesh of a composite render (see the module notes).
#[allow(clippy::too_many_arguments)]
pub(super) fn layers(
    engine: &Engine,
    m: &Scene,
    lin: &[[f32; 3]],
    vc: &ViewCamera,
    p: &RenderParams,
    moved: bool,
    report: &mut RenderReport,
    cache: Option<&mut Option<Base>>,
) -> Result<Layers> {
    let photo = m.photo.as_ref().expect("checked by the caller");
    let cam0 = m.camera.expect("checked by the caller");
    let (pw, ph) = photo.dimensions();
    let (pwu, phu) = (pw as usize, ph as usize);
    let hair0 = hair_mask(m, pwu * phu);
    // Strands moved from where the photo saw them (`render_moved`) get the inpainted
    // background at every view: the photo's own hair would show where they left.
    let original = !moved && p.is_original_view() && (vc.width, vc.height) == (pw, ph);
    if original {
        // The photo, recoloured in the hair as the strands are (their photo colour goes
        // through the same HSV step), so uncovered hair reads as the strands beside it; the
        // margin around the mask is mostly background and keeps its colour.
        let sp = &p.shade;
        let hsv = (!sp.hsv_is_identity()).then_some([sp.hue, sp.saturation, sp.value]);
        let bg: Vec<[f32; 4]> = lin
            .iter()
            .zip(&hair0)
            .map(|(c, &hr)| {
                let c = match hsv {
                    Some([h, s, v]) if hr != 0 => colour::hsv_adjust(*c, h, s, v),
                    _ => *c,
                };
                [c[0], c[1], c[2], 1.0]
            })
            .collect();
        // The head hides strands behind it and shows the same picture (screen-space uvs).
        let mesh = m.head.as_ref().map(|hd| {
            let (verts, tris) = hd.mesh(p.head_texture.mesh_res);
            let positions: Vec<[f32; 3]> = verts
                .iter()
                .map(|&v| vc.project(v).unwrap_or([f32::NAN; 3]))
                .collect();
            let uvs = positions
                .iter()
                .map(|q| [q[0] / pw as f32, q[1] / ph as f32])
                .collect();
            ScreenMesh {
                positions,
                uvs,
                triangles: tris,
                texture: Texture {
                    width: pw,
                    height: ph,
                    texels: bg.clone(),
                },
            }
        });
        return Ok(Layers {
            background: bg,
            hole: vec![0; pwu * phu],
            skin: vec![0; pwu * phu],
            mesh,
        });
    }
    // Every novel view of the scene shares its background and its head layer but for the
    // head's pose: a caller drawing many (a simulation's frames) keeps them in `cache`.
    let mut own = None;
    let slot = cache.unwrap_or(&mut own);
    if slot.is_none() {
        *slot = Some(base(engine, m, lin, p, report)?);
    }
    let b = slot.as_ref().expect("filled above");
    report.hole_pixels = b.hole.iter().filter(|&&v| v != 0).count();
    Ok(b.view(&cam0, vc, p))
}

/// What every novel view of a scene shares (see the module notes): the inpainted
/// background, the hole it fills, the photo's skin region and the head layer in model space.
pub struct Base {
    background: Vec<[f32; 4]>,
    hole: Vec<u8>,
    skin: Vec<u8>,
    head: Option<BaseHead>,
}

/// The head layer of a [`Base`]: its mesh in model space, textured and cut, and how the
/// neck twists.
struct BaseHead {
    positions: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    triangles: Vec<[u32; 3]>,
    texture: Texture,
    /// Vertices that turn fully with the head (any triangle above the chin holds them).
    of_head: Vec<bool>,
    /// Photo rows of the lowest visible skin under the face and of the chin.
    bottom: f32,
    chin_y: f32,
}

impl Base {
    /// The layers as the view `vc` with the head turned by `p` sees them. The neck twists:
    /// its vertices turn with the head in proportion to their height between the lowest
    /// visible skin (not turned) and the chin (turned fully).
    fn view(&self, cam0: &WeakPerspective, vc: &ViewCamera, p: &RenderParams) -> Layers {
        let mesh = self.head.as_ref().map(|hd| {
            // The view's model-space turn undone, then redone by a share of the angles.
            let undo = rotation(p).transpose();
            let positions = hd
                .positions
                .iter()
                .zip(&hd.of_head)
                .map(|(&v, &of_head)| {
                    let v = Vec3::from_array(v);
                    let v = if of_head || hd.bottom <= hd.chin_y + 0.5 {
                        v
                    } else {
                        let q = cam0.project(v);
                        let w = ((hd.bottom - q.y) / (hd.bottom - hd.chin_y)).clamp(0.0, 1.0);
                        undo * partial_rotation(p, w) * v
                    };
                    vc.project(v).unwrap_or([f32::NAN; 3])
                })
                .collect();
            ScreenMesh {
                positions,
                uvs: hd.uvs.clone(),
                triangles: hd.triangles.clone(),
                texture: hd.texture.clone(),
            }
        });
        Layers {
            background: self.background.clone(),
            hole: self.hole.clone(),
            skin: self.skin.clone(),
            mesh,
        }
    }
}

/// The scene's hair mask as 1 / 0 (`n` zeros without one).
fn hair_mask(m: &Scene, n: usize) -> Vec<u8> {
    match &m.mask {
        Some(mk) => mk.iter().map(|&v| (v != 0) as u8).collect(),
        None => vec![0; n],
    }
}

/// The [`Base`] of novel views of `m` (see the module notes).
fn base(
    engine: &Engine,
    m: &Scene,
    lin: &[[f32; 3]],
    p: &RenderParams,
    report: &mut RenderReport,
) -> Result<Base> {
    let photo = m.photo.as_ref().expect("checked by the caller");
    let cam0 = m.camera.expect("checked by the caller");
    let (pw, ph) = photo.dimensions();
    let (pwu, phu) = (pw as usize, ph as usize);
    let hair = dilate(
        &hair_mask(m, pwu * phu),
        pwu,
        phu,
        p.hair_margin_px as usize,
    );
    let head = m.head.as_ref();
    // The head mesh once, in model space and as the photo's camera sees it.
    let head_mesh = head.map(|hd| {
        let (verts, tris) = hd.mesh(p.head_texture.mesh_res);
        let seen = crate::model::volume::Mesh {
            verts: verts.iter().map(|&v| cam0.project(v).to_array()).collect(),
            tris: tris.clone(),
        };
        (verts, tris, seen)
    });
    // Pixels of the photo a mesh covers.
    let covered = |mesh: &crate::model::volume::Mesh| -> Result<Vec<bool>> {
        let dm = crate::model::volume::rasterize_depth(engine, pw, ph, &[mesh])?;
        Ok((0..pwu * phu).map(|i| dm.covered(i)).collect())
    };
    let chin = head.and_then(|hd| hd.landmark("chin"));
    let (Some(head), Some((_, _, seen)), Some(chin)) = (head, head_mesh, chin) else {
        // No head: only the hair leaves the background.
        report.hole_pixels = hair.iter().filter(|&&v| v != 0).count();
        let (filled, _) = inpaint(engine, pw, ph, lin, &hair, &p.inpaint)?;
        return Ok(Base {
            background: filled.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect(),
            hole: hair,
            skin: vec![0; pwu * phu],
            head: None,
        });
    };
    let skin = skin_mask(lin, pw, ph, head, &cam0, &hair);
    let inner = inner_face(head, &cam0, pw, ph);
    // The inner face's box reaches past a narrow face's outline at the jaw and the temples
    // (backdrop, collar); there it put backdrop colour on the texture and into the hole,
    // which a turned head showed as a pale bar beside the jaw. Features lie between skin on
    // both sides, so per row only the span between the outermost skin pixels counts (the
    // rows around lend none: wider cheek rows brought the backdrop back at the jaw).
    let spans: Vec<Option<(usize, usize)>> = skin
        .chunks(pwu)
        .map(|row| {
            let a = row.iter().position(|&v| v != 0)?;
            Some((a, row.iter().rposition(|&v| v != 0)?))
        })
        .collect();
    let face: Vec<u8> = (0..pwu * phu)
        .map(|i| {
            let (x, y) = (i % pwu, i / pwu);
            let within = spans[y].is_some_and(|(a, b)| x >= a && x <= b);
            skin[i] | (inner[i] & within as u8)
        })
        .collect();
    // The head layer fitted to the photo face's width, wider or narrower (see
    // `face_warp`): every photo-side use of the head's points below goes through `proj0`.
    let seen_px = covered(&seen)?;
    let warp = FaceWarp::fit(&seen_px, &face, &hair, pwu, phu, head, &cam0);
    let proj0 = |v: Vec3| warp.map(cam0.project(v));
    // The face texture from the photo where skin (or the inner face) shows, the rest
    // filled; the texture is taken from the photo and masks pulled through the map, so each
    // texel shows the photo pixel its moved point lands on (the moved head covers the map of
    // every pixel the fitted one covers).
    // (Rows the map leaves alone are copied as they are.)
    let nearer = |a: u8, b: u8, t: f32| if t < 0.5 { a } else { b };
    let lerp = |a: [f32; 3], b: [f32; 3], t: f32| std::array::from_fn(|k| a[k] + (b[k] - a[k]) * t);
    let lin_w = warp.pull(lin, pwu, phu, lerp);
    let (hair_w, face_w) = (
        warp.pull(&hair, pwu, phu, nearer),
        warp.pull(&face, pwu, phu, nearer),
    );
    let usable_w: Vec<u8> = (0..pwu * phu)
        .map(|i| (seen_px[i] && hair_w[i] == 0 && face_w[i] != 0) as u8)
        .collect();
    let th = head_texture_with(
        engine,
        head,
        &cam0,
        &lin_w,
        pw,
        ph,
        &usable_w,
        &p.head_texture,
    )?;
    let at = |m: &[u8], q: Vec3| {
        let (x, y) = (q.x.floor(), q.y.floor());
        x >= 0.0
            && y >= 0.0
            && x < pw as f32
            && y < ph as f32
            && m[y as usize * pwu + x as usize] != 0
    };
    // Triangles the photo shows as something else than head (clothing, background) go:
    // below the chin only skin stays (the neck); above it, a triangle facing the photo's
    // camera stays when it lands on face or hair (a few px of slack for the fit).
    let head_or_hair: Vec<u8> = face.iter().zip(&hair).map(|(&a, &b)| a | b).collect();
    let head_or_hair = dilate(&head_or_hair, pwu, phu, 3);
    let toward0 = cam0.r.row(2);
    let mouth_y = match (head.landmark("mouth_left"), head.landmark("mouth_right")) {
        (Some(a), Some(b)) => 0.5 * (a.y + b.y),
        _ => chin.y,
    };
    let mut above = Vec::new();
    let triangles: Vec<[u32; 3]> = th
        .triangles
        .iter()
        .copied()
        .filter(|t| {
            let v = t.map(|i| Vec3::from(th.positions[i as usize]));
            let q = proj0((v[0] + v[1] + v[2]) / 3.0);
            let facing = (v[1] - v[0]).cross(v[2] - v[0]).dot(toward0) > 0.0;
            // A triangle over the edge of what the photo shows stays when its centre or a
            // corner is inside: the texture's alpha (below) then cuts it along the photo's
            // own pixels.
            let inside = |m: &[u8]| at(m, q) || v.iter().any(|&c| at(m, proj0(c)));
            if v.iter().all(|q| q.y <= chin.y) {
                facing && inside(&skin)
            } else if facing {
                let keep = inside(&head_or_hair);
                if keep {
                    above.push(*t);
                }
                keep
            } else {
                // Turned away from the photo's camera: the photo says nothing about it. The
                // back of the skull stays; below the mouth it is the jaw's back and the
                // neck's far side, which a novel view would show as a pale slab of guessed
                // skin beside the neck, so it goes (the inpainted background shows there).
                v.iter().any(|q| q.y > mouth_y)
            }
        })
        .collect();
    // The photo's head leaves the background: the face pixels the kept head covers and the
    // hair, grown by the hair margin and a few px for the fit. Clothing and the neck stay.
    let proj: Vec<[f32; 3]> = th
        .positions
        .iter()
        .map(|&v| proj0(Vec3::from(v)).to_array())
        .collect();
    let above_px = covered(&crate::model::volume::Mesh {
        verts: proj,
        tris: above,
    })?;
    let chin_px = cam0.project(chin);
    let head_px: Vec<u8> = (0..pwu * phu)
        .map(|i| (above_px[i] && face[i] != 0 && (i / pwu) as f32 + 0.5 <= chin_px.y) as u8)
        .collect();
    let head_px = dilate(&head_px, pwu, phu, p.hair_margin_px as usize + 3);
    let hole: Vec<u8> = hair
        .iter()
        .zip(&head_px)
        .map(|(&a, &b)| (a != 0 || b != 0) as u8)
        .collect();
    report.hole_pixels = hole.iter().filter(|&&v| v != 0).count();
    // Behind the face below the mouth is the neck: that part of the hole takes the colour
    // under the chin (neck or collar), not PatchMatch's, which fills it from the backdrop
    // and leaves a pale strip beside the jaw where a turned head uncovers it.
    let mut lin_pre = lin.to_vec();
    let mut hole_pm = hole.clone();
    if let (Some(neck), Some((_, mouth, _))) = (
        colour_under_chin(lin, &hole, pw, ph, head, &cam0),
        face_frame(head, &cam0),
    ) {
        // Only as wide as the photo's neck: a block the width of the face showed beside the
        // jaw of a turned head as a slab of the neck's shadow where the backdrop belongs.
        let (a, b) = neck_columns(&hole, &skin, pw, ph, head, &cam0).unwrap_or((0, pwu));
        for i in 0..pwu * phu {
            let x = i % pwu;
            if head_px[i] != 0
                && hair[i] == 0
                && (i / pwu) as f32 + 0.5 >= mouth.y
                && (a..=b).contains(&x)
            {
                lin_pre[i] = neck;
                hole_pm[i] = 0;
            }
        }
    }
    // The hole depends on the photo's camera only, so every novel view gets the same fill.
    let (filled, _) = inpaint(engine, pw, ph, &lin_pre, &hole_pm, &p.inpaint)?;
    let background: Vec<[f32; 4]> = filled.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect();

    // The lowest photo row of skin below the chin, under the face.
    let bottom = lowest_skin_row(&skin, pw, ph, chin_px.truncate()).unwrap_or(chin_px.y);
    // Only vertices of the neck alone twist: one shared with a head triangle turns fully,
    // or a triangle spanning the chin would stretch between a turned and an unturned corner.
    let mut of_head = vec![false; th.positions.len()];
    for t in &triangles {
        if t.iter().any(|&i| th.positions[i as usize][1] > chin.y) {
            for &i in t {
                of_head[i as usize] = true;
            }
        }
    }
    let (tw, tht, mut texels) = th.texture;
    // Per texel, whether the photo shows head where it sees the texel: below the chin its
    // skin (the neck ends where the photo's neck does), above it face or hair with the
    // small holes closed (eyes, shadows). As the texture's alpha this cuts the mesh along the
    // photo's pixels, anti-aliased, where the triangles alone left a saw-tooth of their own
    // size along the jaw and the collar. Texels turned away from the photo keep alpha 1 on
    // the scalp and 0 elsewhere ([`unseen_texel_stays`]): the photo says nothing about them.
    // The hair grown by its margin, as the skin leaves it out: no gap between the two.
    let mut shown: Vec<bool> = face.iter().zip(&hair).map(|(&a, &b)| a | b != 0).collect();
    crate::base::mask::fill_holes(&mut shown, pwu, phu, 0.01);
    // Softened (a 3x3 box twice) so the cut follows the region's shape, not the 1-px
    // steps of a binary mask's edge.
    let soft = |v: Vec<f32>| {
        let once = crate::base::filter::box_mean(&v, pwu, phu, 1);
        crate::base::filter::box_mean(&once, pwu, phu, 1)
    };
    let shown = soft(shown.iter().map(|&b| b as u8 as f32).collect());
    let skin_soft = soft(skin.iter().map(|&v| (v != 0) as u8 as f32).collect());
    for (t, s) in texels.iter_mut().zip(&th.surface) {
        let Some(s) = s else { continue };
        if s.normal.dot(toward0) <= 0.0 {
            if !unseen_texel_stays(head, s.pos) {
                t[3] = 0.0;
            }
            continue;
        }
        // Texels the photo sees edge-on (the head's side beside the face outline) are cut
        // too: kept, a turned view unfolds those few px into a slab of guessed colour.
        let m = if s.pos.y <= chin.y {
            &skin_soft
        } else {
            &shown
        };
        t[3] = coverage_at(m, pwu, phu, proj0(s.pos).truncate());
    }
    // The mesh itself moved: each vertex across the photo's view, at its own depth.
    let positions = th
        .positions
        .iter()
        .map(|&v| cam0.unproject(proj0(Vec3::from(v))).to_array())
        .collect();
    Ok(Base {
        background,
        hole,
        skin,
        head: Some(BaseHead {
            positions,
            uvs: th.uvs,
            triangles,
            texture: Texture {
                width: tw,
                height: tht,
                texels,
            },
            of_head,
            bottom,
            chin_y: chin_px.y,
        }),
    })
}

/// Whether a head texel turned away from the photo's camera stays in the head layer: only
/// on the scalp, where the skull hides the far side's strands. Elsewhere (behind the ears,
/// the nape, the back of the neck) the photo says nothing and no strand grows; where the
/// fitted head is wider than the photo's, a turned view showed that part as a ribbon of
/// guessed skin hanging beside the face, cut off from it. Cut, the inpainted background
/// shows there, as it does beside the turned cheek.
pub fn unseen_texel_stays(head: &Head, pos: Vec3) -> bool {
    head.scalp_uv(pos).is_some() && !head.in_face(pos)
}

/// Soft mask `m` (w x h, in [0, 1]) bilinear at photo point `q` (pixel centres at +0.5),
/// 0 outside.
fn coverage_at(m: &[f32], w: usize, h: usize, q: Vec2) -> f32 {
    let (fx, fy) = (q.x - 0.5, q.y - 0.5);
    if !(fx.is_finite() && fy.is_finite()) {
        return 0.0;
    }
    let (x0, y0) = (fx.floor(), fy.floor());
    let (ax, ay) = (fx - x0, fy - y0);
    let at = |x: f32, y: f32| -> f32 {
        let inside = x >= 0.0 && y >= 0.0 && x < w as f32 && y < h as f32;
        if inside {
            m[y as usize * w + x as usize]
        } else {
            0.0
        }
    };
    let top = at(x0, y0) * (1.0 - ax) + at(x0 + 1.0, y0) * ax;
    let bottom = at(x0, y0 + 1.0) * (1.0 - ax) + at(x0 + 1.0, y0 + 1.0) * ax;
    top * (1.0 - ay) + bottom * ay
}

/// The view's turn scaled by `w` (0 = none, 1 = all of it).
fn partial_rotation(p: &RenderParams, w: f32) -> Mat3 {
    rotation(&RenderParams {
        yaw_deg: w * p.yaw_deg,
        pitch_deg: w * p.pitch_deg,
        roll_deg: w * p.roll_deg,
        ..RenderParams::default()
    })
}

/// Landmarks as the photo sees them: eyes' midpoint, mouth's midpoint, eye distance (px).
fn face_frame(head: &Head, cam: &WeakPerspective) -> Option<(Vec2, Vec2, f32)> {
    let at = |n: &str| head.landmark(n).map(|q| cam.project(q).truncate());
    let (le, re) = (at("left_eye")?, at("right_eye")?);
    let (ml, mr) = (at("mouth_left")?, at("mouth_right")?);
    let d = (re - le).length();
    (d.is_finite() && d > 1.0).then_some((0.5 * (le + re), 0.5 * (ml + mr), d))
}

/// The photo pixels of a box under the chin, `half` eye distances either side of it and
/// from `top` to `bottom` eye distances below it, clipped to the w × h photo: (columns,
/// rows). None without eyes, mouth or chin.
fn box_under_chin(
    head: &Head,
    cam: &WeakPerspective,
    w: u32,
    h: u32,
    half: f32,
    top: f32,
    bottom: f32,
) -> Option<(std::ops::Range<usize>, std::ops::Range<usize>)> {
    let (_, _, d) = face_frame(head, cam)?;
    let chin = cam.project(head.landmark("chin")?).truncate();
    let span = |a: f32, b: f32, n: u32| (a.max(0.0) as usize)..(b.min(n as f32).max(0.0) as usize);
    Some((
        span(chin.x - half * d, chin.x + half * d, w),
        span(chin.y + top * d, chin.y + bottom * d, h),
    ))
}

/// The median colour (per channel) of the photo under the chin, outside the hole: a box
/// 0.8 eye distances wide from 0.15 to 0.6 eye distances under the chin. None when it holds
/// fewer than 8 such pixels.
fn colour_under_chin(
    lin: &[[f32; 3]],
    hole: &[u8],
    w: u32,
    h: u32,
    head: &Head,
    cam: &WeakPerspective,
) -> Option<[f32; 3]> {
    let (xs, ys) = box_under_chin(head, cam, w, h, 0.4, 0.15, 0.6)?;
    let mut px: Vec<[f32; 3]> = Vec::new();
    for y in ys {
        for x in xs.clone() {
            let i = y * w as usize + x;
            if hole[i] == 0 {
                px.push(lin[i]);
            }
        }
    }
    if px.len() < 8 {
        return None;
    }
    let mut out = [0.0f32; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut v: Vec<f32> = px.iter().map(|c| c[k]).collect();
        v.sort_by(f32::total_cmp);
        *o = v[v.len() / 2];
    }
    Some(out)
}

/// The columns of the photo's neck under the chin: from the leftmost to the rightmost skin
/// pixel outside the hole between the chin and 0.6 eye distances under it, within 0.8 eye
/// distances of the chin, grown by 2 px. None when the photo shows fewer than 8 such
/// pixels (a collar up to the chin).
fn neck_columns(
    hole: &[u8],
    skin: &[u8],
    w: u32,
    h: u32,
    head: &Head,
    cam: &WeakPerspective,
) -> Option<(usize, usize)> {
    let (xs, ys) = box_under_chin(head, cam, w, h, 0.8, 0.0, 0.6)?;
    let wu = w as usize;
    let (mut n, mut first, mut last) = (0, usize::MAX, 0);
    for y in ys {
        for x in xs.clone() {
            let i = y * wu + x;
            if hole[i] == 0 && skin[i] != 0 {
                n += 1;
                first = first.min(x);
                last = last.max(x);
            }
        }
    }
    (n >= 8).then(|| (first.saturating_sub(2), (last + 2).min(wu - 1)))
}

/// The inner face (brows, eyes, nose, mouth) in the photo: features whose colour is not
/// skin but which belong on the face texture. A rounded box (a superellipse of degree 4)
/// from above the brows (0.75 eye distances over the eyes) to below the lower lip (0.35
/// under the mouth), 1.05 eye distances either side, inside the face's outline.
fn inner_face(head: &Head, cam: &WeakPerspective, w: u32, h: u32) -> Vec<u8> {
    let mut out = vec![0u8; (w * h) as usize];
    let Some((eyes, mouth, d)) = face_frame(head, cam) else {
        return out;
    };
    let (top, bottom) = (eyes.y - 0.75 * d, mouth.y + 0.35 * d);
    let c = Vec2::new(0.5 * (eyes.x + mouth.x), 0.5 * (top + bottom));
    let (ax, ay) = (1.05 * d, 0.5 * (bottom - top));
    for y in 0..h {
        for x in 0..w {
            let q = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - c;
            if (q.x / ax).powi(4) + (q.y / ay).powi(4) <= 1.0 {
                out[(y * w + x) as usize] = 1;
            }
        }
    }
    out
}

/// The photo's skin around the fitted face (face and neck): pixels whose chromaticity
/// (r, g = R/Σ, G/Σ of linear RGB) lies within 3 robust deviations (1.4826·MAD) + 0.015 of
/// the cheeks' median and whose brightness Σ lies within 0.15..3 times theirs (shadow under
/// the chin), connected to the cheeks (between the eyes and the mouth) inside a window one
/// and a half eye distances either side of the face and below the chin, never hair.
/// Clothing and background differ in colour or brightness and so stay out. All zero when the
/// cheeks give too few samples.
pub fn skin_mask(
    lin: &[[f32; 3]],
    w: u32,
    h: u32,
    head: &Head,
    cam: &WeakPerspective,
    hair: &[u8],
) -> Vec<u8> {
    let (wu, hu) = (w as usize, h as usize);
    let mut out = vec![0u8; wu * hu];
    let (Some((eyes, mouth, d)), Some(chin)) = (face_frame(head, cam), head.landmark("chin"))
    else {
        return out;
    };
    let chin = cam.project(chin).truncate();
    let chroma = |c: [f32; 3]| {
        let s = c[0] + c[1] + c[2];
        (s > 1e-4).then(|| [c[0] / s, c[1] / s, s])
    };
    // Cheeks and nose: below the eyes, above the mouth, between the outer eye corners.
    let (x0, x1) = (eyes.x - 0.6 * d, eyes.x + 0.6 * d);
    let (y0, y1) = (eyes.y + 0.3 * d, mouth.y - 0.1 * d);
    let mut samples: Vec<[f32; 3]> = Vec::new();
    let mut seeds = Vec::new();
    for y in (y0.max(0.0) as usize)..(y1.max(0.0) as usize).min(hu) {
        for x in (x0.max(0.0) as usize)..(x1.max(0.0) as usize).min(wu) {
            let i = y * wu + x;
            if hair[i] != 0 {
                continue;
            }
            if let Some(c) = chroma(lin[i]) {
                samples.push(c);
                seeds.push(i);
            }
        }
    }
    if samples.len() < 20 {
        return out;
    }
    let median = |k: usize| {
        let mut v: Vec<f32> = samples.iter().map(|s| s[k]).collect();
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    let mad = |k: usize, m: f32| {
        let mut v: Vec<f32> = samples.iter().map(|s| (s[k] - m).abs()).collect();
        v.sort_by(f32::total_cmp);
        v[v.len() / 2]
    };
    let (mr, mg, ms) = (median(0), median(1), median(2));
    let (tr, tg) = (
        3.0 * 1.4826 * mad(0, mr) + 0.015,
        3.0 * 1.4826 * mad(1, mg) + 0.015,
    );
    let (wx0, wx1) = (eyes.x - 1.5 * d, eyes.x + 1.5 * d);
    let (wy0, wy1) = (eyes.y - 1.2 * d, chin.y + 1.5 * d);
    // The backdrop beside the face (a quarter eye distance just outside the window, from
    // the eyes to the chin, not hair). A pale, warm backdrop can lie within the cheeks'
    // tolerance (the astronaut's: r 0.36 against 0.48 ± 0.12), and the fill then ran along
    // the jaw into it, so a pixel also has to be nearer the cheeks than the backdrop. Only
    // when the cheeks lie outside the backdrop's own tolerance (a skin-coloured backdrop
    // would otherwise cut the skin in half).
    let mut side: Vec<[f32; 3]> = Vec::new();
    for y in (eyes.y.max(0.0) as usize)..(chin.y.max(0.0) as usize).min(hu) {
        for (a, b) in [(wx0 - 0.25 * d, wx0), (wx1, wx1 + 0.25 * d)] {
            for x in (a.max(0.0) as usize)..(b.max(0.0) as usize).min(wu) {
                let i = y * wu + x;
                if hair[i] == 0 {
                    side.extend(chroma(lin[i]));
                }
            }
        }
    }
    let backdrop = (side.len() >= 20)
        .then(|| {
            let stat = |k: usize| {
                let mut v: Vec<f32> = side.iter().map(|s| s[k]).collect();
                v.sort_by(f32::total_cmp);
                let m = v[v.len() / 2];
                let mut dv: Vec<f32> = v.iter().map(|x| (x - m).abs()).collect();
                dv.sort_by(f32::total_cmp);
                (m, 3.0 * 1.4826 * dv[dv.len() / 2] + 0.015)
            };
            (stat(0), stat(1))
        })
        .filter(|&((br, sr), (bg, sg))| (br - mr).abs() > sr || (bg - mg).abs() > sg)
        .map(|((br, _), (bg, _))| (br, bg));
    let is_skin = |i: usize| {
        let (x, y) = ((i % wu) as f32 + 0.5, (i / wu) as f32 + 0.5);
        if hair[i] != 0 || x < wx0 || x > wx1 || y < wy0 || y > wy1 {
            return false;
        }
        chroma(lin[i]).is_some_and(|c| {
            let dist = |r: f32, g: f32| ((c[0] - r) / tr).powi(2) + ((c[1] - g) / tg).powi(2);
            (c[0] - mr).abs() <= tr
                && (c[1] - mg).abs() <= tg
                && c[2] >= 0.15 * ms
                && c[2] <= 3.0 * ms
                && backdrop.is_none_or(|(br, bg)| dist(mr, mg) < dist(br, bg))
        })
    };
    let mut stack: Vec<usize> = seeds.into_iter().filter(|&i| is_skin(i)).collect();
    for &i in &stack {
        out[i] = 1;
    }
    while let Some(i) = stack.pop() {
        let (x, y) = (i % wu, i / wu);
        let nb = [
            (x > 0).then(|| i - 1),
            (x + 1 < wu).then(|| i + 1),
            (y > 0).then(|| i - wu),
            (y + 1 < hu).then(|| i + wu),
        ];
        for j in nb.into_iter().flatten() {
            if out[j] == 0 && is_skin(j) {
                out[j] = 1;
                stack.push(j);
            }
        }
    }
    // A closing fills pores and specular specks without growing the outline.
    erode(&dilate(&out, wu, hu, 1), wu, hu, 1)
}

/// The bottom edge (photo px) of the lowest row holding skin below `chin` (the skin mask is
/// already confined to the face's window); None when no skin lies below the chin.
fn lowest_skin_row(skin: &[u8], w: u32, h: u32, chin: Vec2) -> Option<f32> {
    let (wu, hu) = (w as usize, h as usize);
    let y0 = (chin.y.max(0.0) as usize).min(hu);
    (y0..hu)
        .rev()
        .find(|&y| skin[y * wu..(y + 1) * wu].iter().any(|&v| v != 0))
        .map(|y| y as f32 + 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The neck's fill is as wide as the photo's skin under the chin, not the face: the
    /// columns run from the outermost skin pixel outside the hole (grown by 2 px), and a
    /// photo with no skin under the chin leaves the caller its whole-width fallback.
    #[test]
    fn neck_columns_follow_the_skin_under_the_chin() {
        let head = Head::default();
        let cam = WeakPerspective {
            s: 1000.0,
            r: Mat3::IDENTITY,
            // The chin about the middle of the frame.
            t: Vec2::new(128.0, -14.0),
        };
        let (w, h) = (256u32, 256u32);
        let (_, _, d) = face_frame(&head, &cam).expect("default head has eyes and mouth");
        let chin = cam.project(head.landmark("chin").unwrap()).truncate();
        let (cx, cy) = (chin.x as usize, chin.y as usize);
        let mut skin = vec![0u8; (w * h) as usize];
        let mut hole = vec![0u8; (w * h) as usize];
        // A neck 12 px either side of the chin, under a face hole reaching 3 px below it,
        // and skin-coloured shoulders farther down than the band looks.
        let band = (0.6 * d) as usize;
        for y in cy..(cy + band + 20).min(h as usize) {
            for x in 0..w as usize {
                let i = y * w as usize + x;
                let neck = x + 12 >= cx && x <= cx + 12;
                skin[i] = (neck || y > cy + band + 2) as u8;
                hole[i] = (y < cy + 3) as u8;
            }
        }
        let (a, b) = neck_columns(&hole, &skin, w, h, &head, &cam).expect("a neck is shown");
        assert_eq!((a, b), (cx - 14, cx + 14));
        // Skin only inside the hole: nothing the photo shows.
        let covered = vec![1u8; (w * h) as usize];
        assert_eq!(neck_columns(&covered, &skin, w, h, &head, &cam), None);
    }

    /// Turned-away texels stay on the back of the skull and go around the ears and on the
    /// back of the neck (what a turned view showed as a ribbon beside the face).
    #[test]
    fn unseen_texels_stay_on_the_back_of_the_skull_only() {
        let head = Head::default();
        let lm = |n: &str| head.landmark(n).expect("default head landmark");
        let (eye_y, chin_y) = (lm("nose_bridge").y, lm("chin").y);
        let ears = [lm("left_ear"), lm("right_ear")];
        let (verts, tris) = head.mesh(48);
        let mut normals = vec![Vec3::ZERO; verts.len()];
        for t in &tris {
            let v = t.map(|i| verts[i as usize]);
            let n = (v[1] - v[0]).cross(v[2] - v[0]);
            for &i in t {
                normals[i as usize] += n;
            }
        }
        // [cut, kept] counts of surface points turned away from a frontal camera (+z).
        let (mut skull, mut ear, mut neck) = ([0usize; 2], [0usize; 2], [0usize; 2]);
        for (v, n) in verts.iter().zip(&normals) {
            if n.z >= 0.0 {
                continue;
            }
            let kept = unseen_texel_stays(&head, *v) as usize;
            if v.y > eye_y + 0.04 && v.x.abs() < 0.05 {
                skull[kept] += 1;
            } else if ears.iter().any(|e| e.distance(*v) < 0.025) {
                ear[kept] += 1;
            } else if v.y < chin_y {
                neck[kept] += 1;
            }
        }
        assert!(
            skull[1] > 50 && skull[0] == 0,
            "back of the skull: {skull:?}"
        );
        assert!(ear[0] > 5 && ear[1] == 0, "around the ears: {ear:?}");
        assert!(neck[0] > 50 && neck[1] == 0, "back of the neck: {neck:?}");
    }
}
