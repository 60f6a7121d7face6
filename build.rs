//! Compiles every shader under `shaders/` to SPIR-V at build time and generates the reflection
//! table the pipeline code uses (`$OUT_DIR/shader_table.rs`, included by `src/gpu/shaders.rs`).
//!
//! - `*.wgsl` goes through naga (WGSL front end, validator with the capabilities the engine
//!   enables, SPIR-V 1.3 back end). A `// variants: NAME = suffix:value ...` line resolves a WGSL
//!   `override` at build time into one SPIR-V module per value, because naga never emits
//!   `override`s as specialization constants.
//! - `*.comp` (GLSL compute) goes through `glslangValidator` (Debian's glslang-tools) with
//!   `--target-env vulkan1.1`, i.e. SPIR-V 1.3. GLSL keeps `constant_id` specialization constants,
//!   which the pipeline code sets by name.
//! - Both kinds are reflected from their SPIR-V by one path (spirq), so descriptor-set layouts,
//!   push-constant ranges and workgroup sizes are never written by hand.
//!
//! Errors name `file:line` and stop the build.

#[path = "tools/build/codegen.rs"]
mod codegen;
#[path = "tools/build/glsl.rs"]
mod glsl;
#[path = "tools/build/reflect.rs"]
mod reflect;
#[path = "tools/build/wgsl.rs"]
mod wgsl;

use std::path::{Path, PathBuf};

/// One compiled SPIR-V module, ready to be reflected.
pub struct CompiledShader {
    /// Table name, e.g. `minmax_u16` (file stem plus variant suffix).
    pub name: String,
    /// Path of the source relative to the crate root, for messages.
    pub source: String,
    /// SPIR-V words.
    pub words: Vec<u32>,
}

fn main() {
    let root = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_else(|_| ".".into()));
    let out_dir =
        PathBuf::from(std::env::var("OUT_DIR").unwrap_or_else(|_| fail("OUT_DIR is not set")));
    let shader_dir = root.join("shaders");
    println!("cargo:rerun-if-changed=shaders");
    // An experiment's switch (tools/build/glsl.rs): spirv-opt flags for the GLSL modules.
    println!("cargo:rerun-if-env-changed=MORPHRAY_SPIRV_OPT");
    for file in [
        "build.rs",
        "tools/build/codegen.rs",
        "tools/build/glsl.rs",
        "tools/build/reflect.rs",
        "tools/build/wgsl.rs",
    ] {
        println!("cargo:rerun-if-changed={file}");
    }

    let mut sources = Vec::new();
    collect_sources(&shader_dir, &mut sources);
    sources.sort();

    let mut compiled = Vec::new();
    for path in &sources {
        println!("cargo:rerun-if-changed={}", path.display());
        let rel = path
            .strip_prefix(&root)
            .unwrap_or(path)
            .display()
            .to_string();
        let result = match path.extension().and_then(|e| e.to_str()) {
            Some("wgsl") => wgsl::compile(path, &rel),
            Some("comp") => glsl::compile(path, &rel, &root, &out_dir),
            _ => continue,
        };
        match result {
            Ok(mut shaders) => compiled.append(&mut shaders),
            Err(message) => fail(&message),
        }
    }

    let mut names = std::collections::BTreeSet::new();
    for shader in &compiled {
        if !names.insert(shader.name.clone()) {
            fail(&format!(
                "{}: a second shader is named `{}`; shader names must be unique",
                shader.source, shader.name
            ));
        }
    }

    let mut entries = Vec::new();
    for shader in &compiled {
        match reflect::reflect(shader) {
            Ok(entry) => entries.push(entry),
            Err(message) => fail(&format!("{}: reflection failed: {message}", shader.source)),
        }
    }
    for shader in &compiled {
        let spv = out_dir.join(format!("{}.spv", shader.name));
        let bytes: Vec<u8> = shader.words.iter().flat_map(|w| w.to_le_bytes()).collect();
        if let Err(e) = std::fs::write(&spv, bytes) {
            fail(&format!("cannot write {}: {e}", spv.display()));
        }
    }
    let table = codegen::table(&entries, &out_dir);
    let table_path = out_dir.join("shader_table.rs");
    if let Err(e) = std::fs::write(&table_path, table) {
        fail(&format!("cannot write {}: {e}", table_path.display()));
    }
}

fn collect_sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        Err(e) => fail(&format!("cannot read {}: {e}", dir.display())),
    };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            collect_sources(&path, out);
        } else if matches!(
            path.extension().and_then(|e| e.to_str()),
            Some("wgsl" | "comp")
        ) {
            out.push(path);
        }
    }
}

/// Stops the build with a message cargo shows verbatim.
fn fail(message: &str) -> ! {
    eprintln!("error: {message}");
    std::process::exit(1);
}
