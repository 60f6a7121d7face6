//! WGSL -> SPIR-V 1.3 through naga, one module per resolved `override` value.
//!
//! Decisions (naga pitfalls):
//! - `lang_version` is (1, 3): with naga's default (1, 0) subgroup code is silently invalid.
//! - The validator gets exactly the capabilities the engine enables on the device: subgroup
//!   operations (basic, vote, arithmetic, ballot) and immediates (push constants). Anything else
//!   fails the build here rather than pipeline creation on a user's machine.
//! - `zero_initialize_workgroup_memory` is off: kernels initialise their shared memory
//!   themselves (naga's polyfill adds stores and a barrier to every workgroup).
//! - `force_loop_bounding` is off: it adds a counter to every loop for a guarantee Vulkan
//!   drivers do not need.
//! - Overrides are resolved here (`process_overrides`), because naga never writes them as
//!   specialization constants; a `// variants: NAME = suffix:value ...` line lists the values.

use crate::CompiledShader;
use naga::back::spv;
use naga::valid::{Capabilities, SubgroupOperationSet, ValidationFlags, Validator};
use std::path::Path;

/// Parses, validates and writes every variant of one WGSL file.
pub fn compile(path: &Path, rel: &str) -> Result<Vec<CompiledShader>, String> {
    let source = std::fs::read_to_string(path).map_err(|e| format!("{rel}: cannot read: {e}"))?;
    let module = naga::front::wgsl::parse_str(&source)
        .map_err(|e| e.emit_to_string_with_path(&source, rel))?;
    let mut validator = Validator::new(ValidationFlags::all(), capabilities());
    validator.subgroup_stages(naga::valid::ShaderStages::COMPUTE);
    validator.subgroup_operations(subgroup_operations());
    let info = validator
        .validate(&module)
        .map_err(|e| e.emit_to_string_with_path(&source, rel))?;

    let stem = path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("shader")
        .to_string();
    let variants = parse_variants(&source, rel)?;
    let mut out = Vec::new();
    let constant_sets: Vec<(String, naga::back::PipelineConstants)> = match &variants {
        None => vec![(stem.clone(), Default::default())],
        Some((name, values)) => values
            .iter()
            .map(|(suffix, value)| {
                let mut constants = naga::back::PipelineConstants::default();
                constants.insert(name.clone(), *value);
                (format!("{stem}_{suffix}"), constants)
            })
            .collect(),
    };
    for (name, constants) in constant_sets {
        let (resolved, resolved_info) =
            naga::back::pipeline_constants::process_overrides(&module, &info, None, &constants)
                .map_err(|e| format!("{rel}: resolving overrides for {name}: {e}"))?;
        let options = spv::Options {
            lang_version: (1, 3),
            flags: spv::WriterFlags::LABEL_VARYINGS | spv::WriterFlags::DEBUG,
            zero_initialize_workgroup_memory: spv::ZeroInitializeWorkgroupMemoryMode::None,
            force_loop_bounding: false,
            use_storage_input_output_16: false,
            ..spv::Options::default()
        };
        let words = spv::write_vec(&resolved, &resolved_info, &options, None)
            .map_err(|e| format!("{rel}: SPIR-V output for {name}: {e}"))?;
        out.push(CompiledShader {
            name,
            source: rel.to_string(),
            words,
        });
    }
    Ok(out)
}

fn capabilities() -> Capabilities {
    Capabilities::SUBGROUP | Capabilities::IMMEDIATES
}

fn subgroup_operations() -> SubgroupOperationSet {
    SubgroupOperationSet::BASIC
        | SubgroupOperationSet::VOTE
        | SubgroupOperationSet::ARITHMETIC
        | SubgroupOperationSet::BALLOT
}

/// Reads `// variants: NAME = suffix:value suffix:value ...` (at most one line per file).
/// An override name and its (suffix, value) variants.
type Variants = (String, Vec<(String, f64)>);

fn parse_variants(source: &str, rel: &str) -> Result<Option<Variants>, String> {
    let mut found = None;
    for (number, line) in source.lines().enumerate() {
        let Some(rest) = line.trim().strip_prefix("// variants:") else {
            continue;
        };
        if found.is_some() {
            return Err(format!(
                "{rel}:{}: only one `// variants:` line is allowed",
                number + 1
            ));
        }
        let (name, list) = rest.split_once('=').ok_or_else(|| {
            format!(
                "{rel}:{}: expected `// variants: NAME = suffix:value ...`",
                number + 1
            )
        })?;
        let mut values = Vec::new();
        for item in list.split_whitespace() {
            let (suffix, value) = item.split_once(':').ok_or_else(|| {
                format!(
                    "{rel}:{}: variant `{item}` is not `suffix:value`",
                    number + 1
                )
            })?;
            let value: f64 = value.parse().map_err(|_| {
                format!(
                    "{rel}:{}: variant value `{value}` is not a number",
                    number + 1
                )
            })?;
            values.push((suffix.to_string(), value));
        }
        if values.is_empty() {
            return Err(format!(
                "{rel}:{}: `// variants:` lists no values",
                number + 1
            ));
        }
        found = Some((name.trim().to_string(), values));
    }
    Ok(found)
}
