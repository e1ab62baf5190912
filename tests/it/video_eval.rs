//! Video tracking against a synthetic clip's exact ground truth (issue 15), small enough for
//! CI: 256², 16 frames, 2,500 strands, cpu backend. The full figures (61 frames,
//! three styles, OpenCV's flows beside ours) come from `cargo bench --bench video`.

use coif::eval::video::{evaluate, EvalOptions};
use coif::gpu::engine::Engine;
use coif::synth::video::VideoParams;
use coif::synth::Style;

#[test]
fn a_synthetic_clip_is_tracked() {
    let mut vp = VideoParams::new(Style::Long, 1, 256, 16);
    vp.strands = 2500;
    let o = EvalOptions {
        drift_frames: vec![15],
        ..Default::default()
    };
    let f = evaluate(&Engine::cpu(), &vp, &o).expect("evaluation");
    let epe = f.flow_epe.iter().sum::<f32>() / f.flow_epe.len() as f32;
    let motion = f.flow_mean_motion.iter().sum::<f32>() / f.flow_mean_motion.len() as f32;
    println!(
        "flow EPE on hair {epe:.3} px; true motion {motion:.3} px per frame (the EPE of no flow)"
    );
    for d in &f.drift {
        println!("{d}");
    }
    println!(
        "3D: median vertex error per frame (mm) {:?}, visible vertices {:?}; roots {:.1e} m; stretch p99 {:.2} %, largest {:.1} %",
        f.vertex_median_mm
            .iter()
            .map(|v| (v * 100.0).round() / 100.0)
            .collect::<Vec<_>>(),
        f.vertex_visible_median_mm
            .iter()
            .map(|v| (v * 100.0).round() / 100.0)
            .collect::<Vec<_>>(),
        f.root_max_m,
        100.0 * f.stretch_p99,
        100.0 * f.stretch_max
    );
    println!(
        "head: yaw error {:.2}° at most (rotation {:.2}°), poses {:?}; features {} of {} on the last frame",
        f.yaw_err_max_deg, f.rot_err_max_deg, f.pose_sources, f.features_last, f.features_reference
    );
    let flicker = f.flicker_ratio.expect("flicker measured");
    let flicker_vertex = f.flicker_vertex_ratio.expect("flicker measured");
    println!(
        "flicker on hair: input {:.2}, re-rendered {:.2}, ratio {flicker:.2}; with the \
         reference's vertex colours {:.2}, ratio {flicker_vertex:.2}; {:.3} s per frame",
        f.flicker_in.unwrap(),
        f.flicker_out.unwrap(),
        f.flicker_vertex_out.unwrap(),
        f.seconds_per_frame
    );
    assert!(
        epe < motion,
        "the flow ({epe} px) is no better than none ({motion} px)"
    );
    // Whether Eq. 6 beats flow alone and features alone is the bench's to say, on the issue's
    // 61-frame clips; on this short, sparse clip it does not (see README): printed above.
    assert!(f.root_max_m <= 1e-5, "roots {} m", f.root_max_m);
    assert!(f.yaw_err_max_deg <= 1.0, "yaw error {}°", f.yaw_err_max_deg);
    assert!(
        !f.pose_sources.contains_key("held"),
        "a frame lost its head pose"
    );
    assert!(flicker <= 1.2, "flicker ratio {flicker}");
    // The photo mode samples each frame under the strands; the reference's vertex colours
    // move only with the tracking, so this is the ratio that sees a jittering strand.
    assert!(
        flicker_vertex <= 1.2,
        "flicker ratio with vertex colours {flicker_vertex}"
    );
}
