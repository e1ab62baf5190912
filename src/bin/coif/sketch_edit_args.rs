//! `coif sketch-edit`'s arguments and their job.
//!
//! Every index on the command line counts from 0 in the *input* sketch: the edits run in a
//! fixed order of kind, the ones that keep the numbering first: flips, moves, contrasts,
//! base edits (each in command-line order), then deletions of curves and of bases (highest
//! index first, so none renumbers another), then added curves and added bases (appended, in
//! command-line order).

use crate::args::Request;
use clap::Args;
use coif::gpu::engine::BackendChoice;
use coif::jobs::{EditStep, Job, SketchEditJob};
use coif::sketch::edit::{BaseEdit, Edit, Rho, Side};
use coif::sketch::{Base, Kind};
use coif::Error;
use std::path::PathBuf;

#[derive(Args)]
pub struct SketchEditArgs {
    /// The sketch to edit: hair.czs, sketch.json or sketch.svg.
    #[arg(long)]
    sketch: PathBuf,
    /// The file to write; its extension (.czs, .json, .svg) names the format.
    #[arg(long)]
    out: PathBuf,
    /// Deletes curve i.
    #[arg(long = "delete", value_name = "I")]
    delete: Vec<usize>,
    /// Flips curve i's direction: i (every label it has), i:l or i:r (one side of an
    /// occluding line). A dividing line cannot be flipped.
    #[arg(long = "flip", value_name = "I[:l|r]")]
    flip: Vec<String>,
    /// Moves curve i by (dx, dy) pixels, rounded to whole pixels: e.g. 3:-4,2.
    #[arg(long = "move", value_name = "I:DX,DY", allow_hyphen_values = true)]
    moves: Vec<String>,
    /// Adds the curves of a file: an SVG drawing (each polyline or path, walked onto the
    /// 5 px / 15° lattice), a sketch (.czs, .json, .svg) or a JSON curve; TYPE (a-e) sets
    /// their kind (a drawn line is otherwise a stream line, e).
    #[arg(long = "add", value_name = "FILE[:TYPE]")]
    add: Vec<String>,
    /// Changes curve i's contrast ρ: i:K or i:*K scales it by K, i:=V sets it to V.
    #[arg(long = "contrast", value_name = "I:[*|=]X")]
    contrast: Vec<String>,
    /// Edits shading base i: i:amp=A,x=X,y=Y,sx=S,sy=S,theta=DEG (any of them).
    #[arg(
        long = "base",
        value_name = "I:FIELD=V,...",
        allow_hyphen_values = true
    )]
    base: Vec<String>,
    /// Deletes shading base i.
    #[arg(long = "delete-base", value_name = "I")]
    delete_base: Vec<usize>,
    /// Adds a shading base: x,y,theta (degrees),sx,sy,amp.
    #[arg(
        long = "add-base",
        value_name = "X,Y,THETA,SX,SY,AMP",
        allow_hyphen_values = true
    )]
    add_base: Vec<String>,
    /// Sets the along/across gradient ratio synthesis adds grain up to (what `coif sketch`
    /// measures on the photo; larger: grainier, shorter-looking strands), or `none` for no
    /// grain.
    #[arg(long = "along-across", value_name = "X|none")]
    along_across: Option<String>,
}

fn invalid(m: String) -> anyhow::Error {
    Error::Invalid(m).into()
}

fn index(t: &str, opt: &str, v: &str) -> anyhow::Result<usize> {
    t.trim().parse().map_err(|_| {
        invalid(format!(
            "--{opt} {v}: \"{t}\" is not an index (a whole number from 0)"
        ))
    })
}

fn number(t: &str, opt: &str, v: &str) -> anyhow::Result<f32> {
    t.trim()
        .parse::<f32>()
        .ok()
        .filter(|x| x.is_finite())
        .ok_or_else(|| invalid(format!("--{opt} {v}: \"{t}\" is not a finite number")))
}

fn split<'a>(v: &'a str, opt: &str, form: &str) -> anyhow::Result<(&'a str, &'a str)> {
    v.split_once(':')
        .ok_or_else(|| invalid(format!("--{opt} {v}: expected {form}")))
}

fn numbers(t: &str, opt: &str, v: &str, n: usize) -> anyhow::Result<Vec<f32>> {
    let x: Vec<f32> = t
        .split(',')
        .map(|p| number(p, opt, v))
        .collect::<anyhow::Result<_>>()?;
    if x.len() != n {
        return Err(invalid(format!(
            "--{opt} {v}: expected {n} numbers separated by commas, got {}",
            x.len()
        )));
    }
    Ok(x)
}

impl SketchEditArgs {
    pub fn request(self) -> anyhow::Result<Request> {
        let mut steps = Vec::new();
        let mut push = |e: Edit| steps.push(EditStep::Edit(e));
        for v in &self.flip {
            let (i, side) = match v.split_once(':') {
                None => (v.as_str(), Side::Both),
                Some((i, "l")) => (i, Side::Left),
                Some((i, "r")) => (i, Side::Right),
                Some(_) => return Err(invalid(format!("--flip {v}: expected I, I:l or I:r"))),
            };
            push(Edit::Flip(index(i, "flip", v)?, side));
        }
        for v in &self.moves {
            let (i, d) = split(v, "move", "I:DX,DY")?;
            let d = numbers(d, "move", v, 2)?;
            push(Edit::Move(index(i, "move", v)?, [d[0], d[1]]));
        }
        for v in &self.contrast {
            let (i, x) = split(v, "contrast", "I:K, I:*K or I:=V")?;
            let r = if let Some(x) = x.strip_prefix('=') {
                Rho::Set(number(x, "contrast", v)?)
            } else {
                Rho::Scale(number(x.strip_prefix('*').unwrap_or(x), "contrast", v)?)
            };
            push(Edit::Contrast(index(i, "contrast", v)?, r));
        }
        for v in &self.base {
            let (i, fields) = split(v, "base", "I:FIELD=V,...")?;
            let mut b = BaseEdit::default();
            for f in fields.split(',') {
                let (name, x) = f
                    .split_once('=')
                    .ok_or_else(|| invalid(format!("--base {v}: \"{f}\" is not FIELD=VALUE")))?;
                let x = number(x, "base", v)?;
                let slot = match name.trim() {
                    "amp" => &mut b.amp,
                    "x" => &mut b.x,
                    "y" => &mut b.y,
                    "sx" => &mut b.sx,
                    "sy" => &mut b.sy,
                    "theta" => &mut b.theta,
                    n => {
                        return Err(invalid(format!(
                            "--base {v}: unknown field \"{n}\" (amp, x, y, sx, sy, theta)"
                        )))
                    }
                };
                *slot = Some(if name.trim() == "theta" {
                    x.to_radians()
                } else {
                    x
                });
            }
            push(Edit::Base(index(i, "base", v)?, b));
        }
        let desc = |list: &[usize], opt: &str| -> anyhow::Result<Vec<usize>> {
            let mut l = list.to_vec();
            l.sort_unstable_by(|a, b| b.cmp(a));
            if let Some(w) = l.windows(2).find(|w| w[0] == w[1]) {
                return Err(invalid(format!("--{opt} {} is given twice", w[0])));
            }
            Ok(l)
        };
        for i in desc(&self.delete, "delete")? {
            push(Edit::Delete(i));
        }
        for i in desc(&self.delete_base, "delete-base")? {
            push(Edit::DeleteBase(i));
        }
        for v in &self.add {
            // A trailing ":a".."e" is the kind; anything else is part of the path.
            let (path, kind) = match v.rsplit_once(':') {
                Some((p, k)) if !p.is_empty() && k.len() == 1 => {
                    let kind = k
                        .chars()
                        .next()
                        .and_then(Kind::from_letter)
                        .ok_or_else(|| {
                            invalid(format!(
                                "--add {v}: TYPE \"{k}\" is not one of a, b, c, d, e"
                            ))
                        })?;
                    (p, Some(kind))
                }
                _ => (v.as_str(), None),
            };
            steps.push(EditStep::AddFile(PathBuf::from(path), kind));
        }
        for v in &self.add_base {
            let x = numbers(v, "add-base", v, 6)?;
            steps.push(EditStep::Edit(Edit::AddBase(Base {
                x: x[0],
                y: x[1],
                theta: x[2].to_radians(),
                sx: x[3],
                sy: x[4],
                amp: x[5],
            })));
        }
        if let Some(v) = &self.along_across {
            let x = if v.trim() == "none" {
                None
            } else {
                match v.trim().parse::<f32>() {
                    Ok(x) if x.is_finite() && x > 0.0 => Some(x),
                    _ => {
                        return Err(invalid(format!(
                            "--along-across {v}: not a positive number or \"none\""
                        )))
                    }
                }
            };
            steps.push(EditStep::Edit(Edit::AlongAcross(x)));
        }
        Ok(Request::Jobs {
            jobs: vec![Job::SketchEdit(SketchEditJob {
                input: self.sketch,
                out: self.out,
                steps,
            })],
            backend: BackendChoice::Cpu,
            max_binding_bytes: None,
            banner: None,
        })
    }
}
