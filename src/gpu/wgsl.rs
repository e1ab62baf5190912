//! Shared WGSL: a shader names the pieces it shares with others by a directive line
//!
//! ```text
//! #include "shared/colour.wgsl"
//! ```
//!
//! (the path relative to `wgsl/`, alone on its line apart from surrounding whitespace), and
//! [`compose`] replaces that line by the piece's text before the source reaches naga or
//! wgpu. WGSL has no preprocessor, so every place that creates a shader module calls
//! [`compose`] first. Pieces may include other pieces; each piece goes in at most once per
//! shader (a second include of it expands to nothing), so two pieces can rely on a common
//! one. Module-scope WGSL declarations are order-independent, so a piece may use globals
//! (bindings, constants) that the including shader declares.
//!
//! The pieces are embedded here with `include_str!`, in [`SHARED`], so a release binary
//! needs no `wgsl/` folder at run time.

use crate::error::{Error, Result};

/// Every shared piece, by its include path (relative to `wgsl/`).
pub const SHARED: &[(&str, &str)] = &[
    (
        "shared/colour.wgsl",
        include_str!("../../wgsl/shared/colour.wgsl"),
    ),
    (
        "shared/cz_tex.wgsl",
        include_str!("../../wgsl/shared/cz_tex.wgsl"),
    ),
    (
        "shared/edit_stroke.wgsl",
        include_str!("../../wgsl/shared/edit_stroke.wgsl"),
    ),
    (
        "shared/field_cfg.wgsl",
        include_str!("../../wgsl/shared/field_cfg.wgsl"),
    ),
    (
        "shared/field_sample.wgsl",
        include_str!("../../wgsl/shared/field_sample.wgsl"),
    ),
    (
        "shared/head_sdf.wgsl",
        include_str!("../../wgsl/shared/head_sdf.wgsl"),
    ),
    (
        "shared/noise.wgsl",
        include_str!("../../wgsl/shared/noise.wgsl"),
    ),
    (
        "shared/field_uv_nb.wgsl",
        include_str!("../../wgsl/shared/field_uv_nb.wgsl"),
    ),
    (
        "shared/orient_theta.wgsl",
        include_str!("../../wgsl/shared/orient_theta.wgsl"),
    ),
    (
        "shared/pm_common.wgsl",
        include_str!("../../wgsl/shared/pm_common.wgsl"),
    ),
    (
        "shared/pm_rand.wgsl",
        include_str!("../../wgsl/shared/pm_rand.wgsl"),
    ),
    (
        "shared/pm_ssd.wgsl",
        include_str!("../../wgsl/shared/pm_ssd.wgsl"),
    ),
    (
        "shared/raster_common.wgsl",
        include_str!("../../wgsl/shared/raster_common.wgsl"),
    ),
    (
        "shared/strand_vis.wgsl",
        include_str!("../../wgsl/shared/strand_vis.wgsl"),
    ),
];

/// The include path of a directive line, or None for any other line.
pub fn include_path(line: &str) -> Option<&str> {
    let rest = line.trim().strip_prefix("#include")?;
    rest.trim().strip_prefix('"')?.strip_suffix('"')
}

/// `src` (the shader `name`, for messages) with every include directive expanded from
/// [`SHARED`]. Fails on an include not in [`SHARED`] and on an include cycle.
pub fn compose(name: &str, src: &str) -> Result<String> {
    compose_with(name, src, &|path| {
        SHARED.iter().find(|(p, _)| *p == path).map(|(_, s)| *s)
    })
}

/// [`compose`] with the pieces looked up by `lookup` (unit tests use their own tables).
pub fn compose_with(
    name: &str,
    src: &str,
    lookup: &dyn Fn(&str) -> Option<&'static str>,
) -> Result<String> {
    let mut state = State {
        name,
        lookup,
        stack: Vec::new(),
        done: Vec::new(),
        out: String::with_capacity(src.len()),
    };
    state.expand(src)?;
    Ok(state.out)
}

struct State<'a> {
    name: &'a str,
    lookup: &'a dyn Fn(&str) -> Option<&'static str>,
    /// The pieces being expanded, outermost first: a path met again here is a cycle.
    stack: Vec<String>,
    /// The pieces already in `out`.
    done: Vec<String>,
    out: String,
}

impl State<'_> {
    fn expand(&mut self, src: &str) -> Result<()> {
        for (k, line) in src.split_inclusive('\n').enumerate() {
            let Some(path) = include_path(line) else {
                self.out.push_str(line);
                continue;
            };
            let within = self
                .stack
                .last()
                .map_or(String::new(), |p| format!(" in {p}"));
            if self.stack.iter().any(|p| p == path) {
                let mut chain = self.stack.clone();
                chain.push(path.to_string());
                return Err(Error::Invalid(format!(
                    "shader {}: include cycle {} (line {}{within})",
                    self.name,
                    chain.join(" -> "),
                    k + 1
                )));
            }
            let Some(text) = (self.lookup)(path) else {
                return Err(Error::Invalid(format!(
                    "shader {}: unknown include \"{path}\" (line {}{within}); shared pieces \
                     are listed in coif::gpu::wgsl::SHARED",
                    self.name,
                    k + 1
                )));
            };
            if self.done.iter().any(|p| p == path) {
                continue;
            }
            self.stack.push(path.to_string());
            self.expand(text)?;
            self.stack.pop();
            self.done.push(path.to_string());
            // A piece without a final newline must not run into the next line.
            if !self.out.ends_with('\n') {
                self.out.push('\n');
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(path: &str) -> Option<&'static str> {
        match path {
            "a.wgsl" => Some("const A: u32 = 1u;\n"),
            "b.wgsl" => Some("#include \"a.wgsl\"\nconst B: u32 = A;"),
            "loop1.wgsl" => Some("#include \"loop2.wgsl\"\n"),
            "loop2.wgsl" => Some("  #include \"loop1.wgsl\"  \n"),
            "self.wgsl" => Some("#include \"self.wgsl\"\n"),
            _ => None,
        }
    }

    #[test]
    fn expands_nested_includes_once() {
        let src = "#include \"b.wgsl\"\n#include \"a.wgsl\"\nfn f() {}\n";
        let out = compose_with("main", src, &table).unwrap();
        assert_eq!(out, "const A: u32 = 1u;\nconst B: u32 = A;\nfn f() {}\n");
    }

    #[test]
    fn leaves_other_lines_alone() {
        let src = "// #include \"x.wgsl\" in a comment\nfn f() {}";
        assert_eq!(compose_with("main", src, &table).unwrap(), src);
        assert_eq!(include_path(" #include \"p/q.wgsl\" "), Some("p/q.wgsl"));
        assert_eq!(include_path("#includes \"q\""), None);
    }

    #[test]
    fn an_unknown_include_names_the_shader_and_the_path() {
        let err = compose_with("pm_cost", "#include \"nope.wgsl\"\n", &table)
            .unwrap_err()
            .to_string();
        assert!(err.contains("shader pm_cost"), "{err}");
        assert!(err.contains("unknown include \"nope.wgsl\""), "{err}");
        // Through the real table too.
        let err = compose("gabor", "fn f() {}\n#include \"shared/nope.wgsl\"\n")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("shader gabor")
                && err.contains("shared/nope.wgsl")
                && err.contains("line 2"),
            "{err}"
        );
    }

    #[test]
    fn an_include_cycle_names_the_shader_and_the_chain() {
        let err = compose_with("strand_raster", "#include \"loop1.wgsl\"\n", &table)
            .unwrap_err()
            .to_string();
        assert!(err.contains("shader strand_raster"), "{err}");
        assert!(
            err.contains("include cycle loop1.wgsl -> loop2.wgsl -> loop1.wgsl"),
            "{err}"
        );
        let err = compose_with("s", "#include \"self.wgsl\"\n", &table)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("include cycle self.wgsl -> self.wgsl"),
            "{err}"
        );
    }

    #[test]
    fn every_shared_piece_composes() {
        for (path, text) in SHARED {
            compose(path, text).unwrap();
        }
    }
}
