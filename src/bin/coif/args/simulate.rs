//! `coif simulate`: mass-spring strands in wind with a keyframed head (C13 §4).

use super::BackendArgs;
use clap::Args;
use coif::jobs::SimulateJob;
use coif::sim::{HeadKey, HeadTrack, SimParams};
use std::path::PathBuf;

/// One channel's keys as one argument value (clap would split a bare Vec into values).
#[derive(Clone, Debug)]
pub struct Keys(Vec<HeadKey>);

fn parse_keys(s: &str) -> Result<Keys, String> {
    coif::sim::track::parse_keys(s).map(Keys)
}

fn parse_vec3(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|x| x.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("expected x,y,z, got {s:?}"))?;
    match v.as_slice() {
        [x, y, z] => Ok([*x, *y, *z]),
        _ => Err(format!("expected x,y,z, got {s:?}")),
    }
}

#[derive(Args)]
pub struct SimulateArgs {
    /// Model folder written by `coif model` (it needs the head).
    #[arg(long)]
    model: PathBuf,
    /// Output folder (created): the scene, frames/NNNN.hair, sim.json, preview.gif.
    #[arg(long)]
    out: PathBuf,
    /// Frames after the rest frame.
    #[arg(long, default_value_t = SimParams::default().frames)]
    frames: u32,
    #[arg(long, default_value_t = SimParams::default().fps)]
    fps: f32,
    /// Steps per frame.
    #[arg(long, default_value_t = SimParams::default().substeps)]
    substeps: u32,
    /// Mean wind speed, m/s (0: still air).
    #[arg(long, default_value_t = SimParams::default().wind)]
    wind: f32,
    /// Wind direction x,y,z in model space (+x image right, +y up, +z toward the camera).
    #[arg(long, value_parser = parse_vec3, allow_hyphen_values = true)]
    wind_dir: Option<[f32; 3]>,
    /// Noise amplitude relative to the mean wind.
    #[arg(long, default_value_t = SimParams::default().gust)]
    gust: f32,
    /// Frame from which the wind stops.
    #[arg(long)]
    wind_until: Option<u32>,
    /// Downward acceleration, m/s² (C13: none; the modelled shape is the rest state).
    #[arg(long, default_value_t = SimParams::default().gravity)]
    gravity: f32,
    /// Vertices per simulated strand.
    #[arg(long, default_value_t = SimParams::default().n_verts)]
    verts: u32,
    #[arg(long, default_value_t = SimParams::default().k_stretch)]
    k_stretch: f32,
    #[arg(long, default_value_t = SimParams::default().k_bend)]
    k_bend: f32,
    #[arg(long, default_value_t = SimParams::default().k_twist)]
    k_twist: f32,
    /// Spring damping as a multiple of stiffness, s.
    #[arg(long, default_value_t = SimParams::default().damping)]
    damping: f32,
    /// Drag toward the wind velocity, 1/s.
    #[arg(long, default_value_t = SimParams::default().drag)]
    drag: f32,
    /// Distance kept from the head, m.
    #[arg(long, default_value_t = SimParams::default().margin)]
    margin: f32,
    /// Largest edge strain after a step (0: springs alone).
    #[arg(long, default_value_t = SimParams::default().strain_limit)]
    strain_limit: f32,
    /// Head yaw keys "frame:degrees,..." (smoothstep between keys).
    #[arg(long, value_parser = parse_keys, allow_hyphen_values = true)]
    head_yaw: Option<Keys>,
    /// Head pitch keys "frame:degrees,...".
    #[arg(long, value_parser = parse_keys, allow_hyphen_values = true)]
    head_pitch: Option<Keys>,
    /// Head roll keys "frame:degrees,...".
    #[arg(long, value_parser = parse_keys, allow_hyphen_values = true)]
    head_roll: Option<Keys>,
    /// Head translation keys "frame:metres,..." along x, y and z.
    #[arg(long, value_parser = parse_keys, allow_hyphen_values = true)]
    head_tx: Option<Keys>,
    #[arg(long, value_parser = parse_keys, allow_hyphen_values = true)]
    head_ty: Option<Keys>,
    #[arg(long, value_parser = parse_keys, allow_hyphen_values = true)]
    head_tz: Option<Keys>,
    #[command(flatten)]
    pub(super) backend: BackendArgs,
}

impl SimulateArgs {
    pub(super) fn job(self) -> SimulateJob {
        let d = SimParams::default();
        let params = SimParams {
            frames: self.frames,
            fps: self.fps,
            substeps: self.substeps,
            n_verts: self.verts,
            k_stretch: self.k_stretch,
            k_bend: self.k_bend,
            k_twist: self.k_twist,
            damping: self.damping,
            drag: self.drag,
            wind: self.wind,
            wind_dir: self.wind_dir.unwrap_or(d.wind_dir),
            gust: self.gust,
            noise_scale: d.noise_scale,
            noise_speed: d.noise_speed,
            wind_until: self.wind_until,
            gravity: self.gravity,
            margin: self.margin,
            strain_limit: self.strain_limit,
            track: HeadTrack {
                yaw: self.head_yaw.map(|k| k.0).unwrap_or_default(),
                pitch: self.head_pitch.map(|k| k.0).unwrap_or_default(),
                roll: self.head_roll.map(|k| k.0).unwrap_or_default(),
                tx: self.head_tx.map(|k| k.0).unwrap_or_default(),
                ty: self.head_ty.map(|k| k.0).unwrap_or_default(),
                tz: self.head_tz.map(|k| k.0).unwrap_or_default(),
            },
        };
        SimulateJob {
            model: self.model,
            out: self.out,
            params,
        }
    }
}
