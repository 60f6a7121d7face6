//! GLSL compute shaders -> SPIR-V 1.3 through `glslangValidator`.
//!
//! Decision: the glslang-tools binary instead of the `glslang` crate. The crate builds glslang
//! from C++ source (about 3 minutes debug, 4.5 release on 2 cores) and `shaderc` does not link
//! against Debian 12's libshaderc; the tool costs nothing to build and about 0.2 s per shader
//! (measured when this was written). `.ci/run` and the README's set-up command install it. Its
//! diagnostics already read `ERROR: shaders/x.comp:12: ...`, which is what a build error should
//! point at.

use crate::CompiledShader;
use std::path::Path;
use std::process::Command;

/// Compiles one `.comp` file; specialization constants stay specializable.
pub fn compile(
    path: &Path,
    rel: &str,
    root: &Path,
    out_dir: &Path,
) -> Result<Vec<CompiledShader>, String> {
    let stem = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("shader")
        .to_string();
    let spv = out_dir.join(format!("{stem}.glslang.spv"));
    let tool = std::env::var("GLSLANG_VALIDATOR").unwrap_or_else(|_| "glslangValidator".into());
    let output = Command::new(&tool)
        .arg("-V")
        .arg("--target-env")
        .arg("vulkan1.1")
        .arg("-Ishaders/include")
        .arg("-o")
        .arg(&spv)
        .arg(rel)
        .current_dir(root)
        .output()
        .map_err(|e| {
            format!(
                "{rel}: cannot run `{tool}` ({e}); install Debian's glslang-tools \
                 (`apt-get install glslang-tools`) or set GLSLANG_VALIDATOR to its path"
            )
        })?;
    if !output.status.success() {
        let text = String::from_utf8_lossy(&output.stdout).to_string()
            + &String::from_utf8_lossy(&output.stderr);
        let errors: Vec<&str> = text
            .lines()
            .filter(|l| l.contains("ERROR") || l.contains("error"))
            .collect();
        return Err(format!("{rel}: glslang failed:\n{}", errors.join("\n")));
    }
    optimize(&spv, rel)?;
    let bytes =
        std::fs::read(&spv).map_err(|e| format!("{rel}: cannot read {}: {e}", spv.display()))?;
    if bytes.len() % 4 != 0 {
        return Err(format!(
            "{rel}: glslang wrote {} bytes, not whole SPIR-V words",
            bytes.len()
        ));
    }
    let words = bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    Ok(vec![CompiledShader {
        name: stem,
        source: rel.to_string(),
        words,
    }])
}

/// Runs spirv-opt over `spv` in place with the flags in MORPHRAY_SPIRV_OPT (nothing when unset or
/// empty): an experiment's switch, off by default because it buys nothing (BENCHMARKS.md
/// "spirv-opt before the driver": -O makes raymarch.comp 5.3x larger, compiles no faster on
/// lavapipe and adds 150-200 ms to the H200's cold first pixel; -Os drops unused push-constant
/// members, which the engine's size check then refuses).
fn optimize(spv: &Path, rel: &str) -> Result<(), String> {
    let flags = std::env::var("MORPHRAY_SPIRV_OPT").unwrap_or_default();
    if flags.trim().is_empty() {
        return Ok(());
    }
    let status = Command::new("spirv-opt")
        .args(flags.split_whitespace())
        .arg(spv)
        .arg("-o")
        .arg(spv)
        .status()
        .map_err(|e| format!("{rel}: cannot run spirv-opt ({e})"))?;
    if status.success() {
        Ok(())
    } else {
        Err(format!("{rel}: spirv-opt failed"))
    }
}
