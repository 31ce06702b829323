//! The WGSL sources, and the modules the GPU path compiles from them.
//!
//! WGSL has no includes, so a module is its files concatenated: the shared hashes
//! first, then a rule's entry point and its plain functions.

/// Every file under `shaders/`, by name, as compiled into the library.
pub const SHADER_FILES: &[(&str, &str)] = &[
    ("hash.wgsl", include_str!("../../shaders/hash.wgsl")),
    ("toroidal.wgsl", include_str!("../../shaders/toroidal.wgsl")),
    ("blend.wgsl", include_str!("../../shaders/blend.wgsl")),
    ("milling.wgsl", include_str!("../../shaders/milling.wgsl")),
    ("shade.wgsl", include_str!("../../shaders/shade.wgsl")),
    ("sampler.wgsl", include_str!("../../shaders/sampler.wgsl")),
    (
        "blend_sampler.wgsl",
        include_str!("../../shaders/blend_sampler.wgsl"),
    ),
    (
        "hash_check.wgsl",
        include_str!("../../shaders/hash_check.wgsl"),
    ),
];

/// The modules the GPU path compiles, by name, each with the files it is made of.
const MODULES: &[(&str, &[&str])] = &[
    ("toroidal", &["hash.wgsl", "toroidal.wgsl"]),
    ("blend", &["hash.wgsl", "blend.wgsl"]),
    ("milling", &["milling.wgsl"]),
    ("shade", &["shade.wgsl"]),
    ("sampler", &["hash.wgsl", "sampler.wgsl"]),
    (
        "blend_sampler",
        &["hash.wgsl", "blend.wgsl", "blend_sampler.wgsl"],
    ),
    ("hash_check", &["hash.wgsl", "hash_check.wgsl"]),
];

/// The source of every module the GPU path compiles, as (name, files, WGSL source).
pub fn composed_modules() -> Vec<(&'static str, &'static [&'static str], String)> {
    MODULES
        .iter()
        .map(|&(name, files)| (name, files, compose(files)))
        .collect()
}

/// The source of module `name`.
pub(crate) fn module(name: &str) -> String {
    let (_, files) = MODULES
        .iter()
        .find(|(n, _)| *n == name)
        .expect("module names are the constants above");
    compose(files)
}

fn compose(files: &[&str]) -> String {
    files
        .iter()
        .map(|f| {
            let (_, text) = SHADER_FILES
                .iter()
                .find(|(n, _)| n == f)
                .expect("module files are listed in SHADER_FILES");
            format!("// ---- {f}\n{text}\n")
        })
        .collect()
}
