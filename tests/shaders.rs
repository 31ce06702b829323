//! Issue 6: every WGSL file parses and validates with naga, with no GPU needed, and the
//! shader twins of the CPU functions keep the CPU names.

use std::collections::BTreeSet;
use std::path::Path;

use surftile::gpu::{SHADER_FILES, composed_modules};

fn validate(name: &str, source: &str) -> naga::Module {
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::default(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)));
    module
}

/// Every module the GPU path compiles parses and validates; every `.wgsl` file in
/// `shaders/` is compiled into the library and used by at least one module, and the
/// compiled copy is the file on disk.
#[test]
fn every_wgsl_file_parses_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let on_disk: BTreeSet<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".wgsl"))
        .collect();
    let compiled: BTreeSet<String> = SHADER_FILES.iter().map(|(n, _)| n.to_string()).collect();
    assert_eq!(on_disk, compiled, "shaders/ and SHADER_FILES differ");
    for (name, text) in SHADER_FILES {
        assert_eq!(
            std::fs::read_to_string(dir.join(name)).unwrap(),
            *text,
            "{name}"
        );
    }
    let mut used = BTreeSet::new();
    let modules = composed_modules();
    assert!(modules.len() >= 3);
    for (name, files, source) in &modules {
        let module = validate(name, source);
        assert!(
            !module.entry_points.is_empty(),
            "module {name} has no entry point"
        );
        used.extend(files.iter().map(|f| f.to_string()));
    }
    // hash.wgsl on its own is a library of plain functions: valid by itself too.
    validate("hash.wgsl", SHADER_FILES[0].1);
    assert_eq!(used, compiled, "a shader file no module uses");
}

/// The WGSL twins carry the names of their Rust functions (STYLE.md), so a reader can
/// find one from the other.
#[test]
fn shader_functions_keep_the_cpu_names() {
    let function_names = |module: &str| -> BTreeSet<String> {
        let (_, _, source) = composed_modules()
            .into_iter()
            .find(|(n, _, _)| *n == module)
            .unwrap();
        let m = naga::front::wgsl::parse_str(&source).unwrap();
        m.functions
            .iter()
            .filter_map(|(_, f)| f.name.clone())
            .collect()
    };
    let expect = |module: &str, names: &[&str]| {
        let have = function_names(module);
        for n in names {
            assert!(have.contains(*n), "{module} lacks {n}: {have:?}");
        }
    };
    expect(
        "hash_check",
        &[
            "fold_cell",
            "pcg4d",
            "hash_tile",
            "hash_vertex",
            "hash_cell",
            "pick_tile",
            "wang_tile",
        ],
    );
    expect("toroidal", &["locate", "tile_of", "texel_at", "bilinear"]);
    expect(
        "blend",
        &[
            "vertex",
            "triangle",
            "lut_eval",
            "bilinear",
            "eval_level",
            "hash_vertex",
        ],
    );
    expect(
        "milling",
        &[
            "part_of",
            "along",
            "weight",
            "shape_plane",
            "atan2_turns",
            "noise_at",
            "value",
            "fold_drawn",
            "adapt",
        ],
    );
    expect(
        "sampler",
        &[
            "surftile_sample",
            "surftile_height",
            "surftile_texel",
            "surftile_tile",
        ],
    );
    expect(
        "blend_sampler",
        &[
            "surftile_sample",
            "surftile_height",
            "vertex",
            "eval_level",
            "lut_eval",
        ],
    );
    expect(
        "shade",
        &["normal_from_gradient", "half_vector", "reflectance"],
    );
}
