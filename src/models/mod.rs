//! Procedural surfaces: models evaluated directly at any point, without tiles.

pub mod fractal;
pub mod milling;
pub mod quilting;
pub mod rsgf;
pub mod rugged;
pub mod synth;
pub mod voronoi;

use crate::error::Error;

/// A TOML parse error as a one-line decode error naming the file and line.
pub(crate) fn toml_error(text: &str, what: &str, e: toml::de::Error) -> Error {
    let line = e
        .span()
        .map(|s| format!("line {}: ", text[..s.start].lines().count().max(1)))
        .unwrap_or_default();
    Error::decode(what, format!("{line}{}", e.message().trim()))
}

/// A TOML configuration read from `path`, or the preset of that name (with or without
/// `.toml`) where no such file exists; a bare name that is no preset is refused as
/// `param`, listing the presets under `kind` ("a milling TOML file"). Returns the value
/// and the folder its relative paths are relative to (none for a preset).
pub(crate) fn preset_or_file<T>(
    path: &std::path::Path,
    presets: &[(&str, &str)],
    param: &str,
    kind: &str,
    parse: impl Fn(&str, &str) -> crate::Result<T>,
) -> crate::Result<(T, Option<std::path::PathBuf>)> {
    if !path.exists()
        && let Some(name) = path.to_str()
    {
        let name = name.trim_end_matches(".toml");
        if let Some((n, text)) = presets.iter().find(|(n, _)| *n == name) {
            return Ok((parse(text, n)?, None));
        }
        if !name.contains(['/', '\\']) {
            let names: Vec<&str> = presets.iter().map(|(n, _)| *n).collect();
            return Err(Error::param(
                param,
                path.display(),
                format!("{kind} or a preset name ({})", names.join(", ")),
            ));
        }
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let value = parse(&text, &path.display().to_string())?;
    Ok((value, path.parent().map(std::path::Path::to_path_buf)))
}
