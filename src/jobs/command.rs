//! The command each job is run by, for `--timings` files and batch stage names.

use super::Job;

impl Job {
    /// The command that runs the job (`coif <command>`).
    pub fn command(&self) -> &'static str {
        match self {
            Job::Synth(_) => "synth",
            Job::SynthVideo(_) => "synth-video",
            Job::Unpack(_) => "unpack",
            Job::Orient(_) => "orient",
            Job::Analyze(_) => "analyze",
            Job::Model(_) => "model",
            Job::Render(_) => "render",
            Job::Simulate(_) => "simulate",
            Job::Edit(_) => "edit",
            Job::Export(_) => "export",
            Job::Import(_) => "import",
            Job::Convert(_) => "convert",
            Job::Video(_) => "video",
            Job::Transfer(_) => "transfer",
            Job::Sketch(_) => "sketch",
            Job::SketchConvert(_) => "sketch-convert",
            Job::SynthHair(_) => "synth-hair",
            Job::Cartoon(_) => "cartoon",
            Job::SketchEdit(_) => "sketch-edit",
        }
    }
}
