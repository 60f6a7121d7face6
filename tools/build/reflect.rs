//! Reflection of compiled SPIR-V: entry point, workgroup size, descriptor bindings, push-constant
//! size and specialization constants, through spirq (a reflection library made for this job).
//!
//! Decision: reflect the SPIR-V, not the sources, so WGSL (naga) and GLSL (glslang) modules are
//! described by one code path and the table matches exactly what the driver will see. Every
//! declared resource is listed (`ref_all_rscs(true)`): spirq's "statically used" analysis misses
//! samplers passed to functions as arguments (shaders/include/sampling.glsl does that), and a
//! layout entry a shader does not use is valid Vulkan, while a missing one is not.

use crate::CompiledShader;
use spirq::prelude::*;
use spirq::ty::{DescriptorType, ScalarType, Type};
use spirq::var::Variable;

/// Kind of one descriptor binding, mirroring `VkDescriptorType`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BindingKind {
    UniformBuffer,
    StorageBuffer { writable: bool },
    UniformTexelBuffer,
    StorageImage { writable: bool },
    CombinedImageSampler,
    SampledImage,
    Sampler,
}

/// Type of one specialization constant.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpecKind {
    Bool,
    U32,
    I32,
    F32,
}

pub struct Binding {
    pub name: String,
    pub set: u32,
    pub binding: u32,
    pub kind: BindingKind,
    pub count: u32,
    pub block_bytes: u32,
}

pub struct SpecConstant {
    pub name: String,
    pub id: u32,
    pub kind: SpecKind,
}

pub struct ReflectedEntry {
    pub name: String,
    pub source: String,
    pub entry_point: String,
    pub workgroup_size: [u32; 3],
    /// Spec ids of the workgroup size when it is specializable (`local_size_x_id` etc.).
    pub workgroup_spec_ids: Option<[u32; 3]>,
    pub bindings: Vec<Binding>,
    pub push_constant_bytes: u32,
    pub spec_constants: Vec<SpecConstant>,
}

/// The SpecIds of a specializable workgroup size, if the module has one: the operands of
/// `OpExecutionModeId LocalSizeId` (SPIR-V 1.2+), or the constituents of the spec-constant
/// composite decorated `BuiltIn WorkgroupSize` (what glslang emits for SPIR-V 1.0-1.1 targets).
fn local_size_spec_ids(words: &[u32]) -> Result<Option<[u32; 3]>, String> {
    const OP_SPEC_CONSTANT_COMPOSITE: u32 = 51;
    const OP_DECORATE: u32 = 71;
    const OP_EXECUTION_MODE_ID: u32 = 331;
    const DECORATION_SPEC_ID: u32 = 1;
    const DECORATION_BUILT_IN: u32 = 11;
    const BUILT_IN_WORKGROUP_SIZE: u32 = 25;
    const MODE_LOCAL_SIZE_ID: u32 = 38;
    let mut spec_ids = std::collections::HashMap::new();
    let mut composites = std::collections::HashMap::new();
    let mut workgroup_builtin = None;
    let mut local_size = None;
    let mut at = 5; // after the header
    while at < words.len() {
        let count = (words[at] >> 16) as usize;
        let opcode = words[at] & 0xffff;
        if count == 0 || at + count > words.len() {
            return Err("malformed SPIR-V instruction stream".into());
        }
        let operands = &words[at + 1..at + count];
        match (opcode, operands) {
            (OP_DECORATE, [target, DECORATION_SPEC_ID, id]) => {
                spec_ids.insert(*target, *id);
            }
            (OP_DECORATE, [target, DECORATION_BUILT_IN, BUILT_IN_WORKGROUP_SIZE]) => {
                workgroup_builtin = Some(*target);
            }
            (OP_SPEC_CONSTANT_COMPOSITE, [_, result, x, y, z]) => {
                composites.insert(*result, [*x, *y, *z]);
            }
            (OP_EXECUTION_MODE_ID, [_, MODE_LOCAL_SIZE_ID, x, y, z]) => {
                local_size = Some([*x, *y, *z]);
            }
            _ => {}
        }
        at += count;
    }
    let Some(ids) =
        local_size.or_else(|| workgroup_builtin.and_then(|b| composites.get(&b).copied()))
    else {
        return Ok(None);
    };
    let mut out = [0; 3];
    for (slot, id) in out.iter_mut().zip(ids) {
        *slot = *spec_ids
            .get(&id)
            .ok_or("LocalSizeId operands must all be specialization constants")?;
    }
    Ok(Some(out))
}

/// Reflects the single compute entry point of one module.
pub fn reflect(shader: &CompiledShader) -> Result<ReflectedEntry, String> {
    let entries = ReflectConfig::new()
        .spv(shader.words.as_slice())
        .ref_all_rscs(true)
        .combine_img_samplers(true)
        .gen_unique_names(false)
        .reflect()
        .map_err(|e| e.to_string())?;
    let compute: Vec<_> = entries
        .iter()
        .filter(|e| e.exec_model == spirq::spirv::ExecutionModel::GLCompute)
        .collect();
    let [entry] = compute.as_slice() else {
        return Err(format!(
            "expected exactly one compute entry point, found {}",
            compute.len()
        ));
    };

    let mut workgroup_size = None;
    // spirq reports `LocalSizeId` as `LocalSize` with the default values and no spec ids, so the
    // ids come from the module's words.
    let workgroup_spec_ids = local_size_spec_ids(&shader.words)?;
    for mode in &entry.exec_modes {
        let by_id = mode.exec_mode == spirq::spirv::ExecutionMode::LocalSizeId;
        if by_id || mode.exec_mode == spirq::spirv::ExecutionMode::LocalSize {
            let dims: Option<Vec<u32>> = mode
                .operands
                .iter()
                // Not `ConstantValue::to_u32`: in spirq 1.3 it only matches signed values.
                .map(|c| match c.value {
                    spirq::constant::ConstantValue::U32(v) => Some(v),
                    spirq::constant::ConstantValue::S32(v) => u32::try_from(v).ok(),
                    _ => None,
                })
                .collect();
            if let Some([x, y, z]) = dims.as_deref().and_then(|d| <[u32; 3]>::try_from(d).ok()) {
                workgroup_size = Some([x, y, z]);
            }
        }
    }
    let workgroup_size = workgroup_size
        .ok_or("the entry point declares no LocalSize (workgroup size) execution mode")?;

    let mut bindings = Vec::new();
    let mut push_constant_bytes = 0;
    let mut spec_constants = Vec::new();
    for var in &entry.vars {
        match var {
            Variable::Descriptor {
                name,
                desc_bind,
                desc_ty,
                nbind,
                ty,
            } => {
                let kind = match desc_ty {
                    DescriptorType::UniformBuffer() => BindingKind::UniformBuffer,
                    DescriptorType::StorageBuffer(access) => BindingKind::StorageBuffer {
                        writable: (*access as u32) & 2 != 0,
                    },
                    DescriptorType::StorageImage(access) => BindingKind::StorageImage {
                        writable: (*access as u32) & 2 != 0,
                    },
                    DescriptorType::CombinedImageSampler() => BindingKind::CombinedImageSampler,
                    DescriptorType::SampledImage() => BindingKind::SampledImage,
                    DescriptorType::Sampler() => BindingKind::Sampler,
                    DescriptorType::UniformTexelBuffer() => BindingKind::UniformTexelBuffer,
                    other => {
                        return Err(format!(
                            "descriptor type {other:?} is not used by the engine"
                        ));
                    }
                };
                let name = name.clone().filter(|n| !n.is_empty()).ok_or_else(|| {
                    format!(
                        "set {} binding {} has no variable name; give the block an instance name \
                         (pipelines bind resources by name)",
                        desc_bind.set(),
                        desc_bind.bind()
                    )
                })?;
                // Fixed part of a buffer block (runtime arrays count as empty); 0 for images.
                let block_bytes = match kind {
                    BindingKind::UniformBuffer | BindingKind::StorageBuffer { .. } => {
                        ty.nbyte().unwrap_or(0) as u32
                    }
                    _ => 0,
                };
                bindings.push(Binding {
                    name,
                    block_bytes,
                    set: desc_bind.set(),
                    binding: desc_bind.bind(),
                    kind,
                    count: (*nbind).max(1),
                });
            }
            Variable::PushConstant { ty, .. } => {
                push_constant_bytes =
                    ty.nbyte().ok_or("push-constant block has no fixed size")? as u32;
            }
            Variable::SpecConstant { spec_id, .. }
                if workgroup_spec_ids.is_some_and(|ids| ids.contains(spec_id)) =>
            {
                // The workgroup size's own constants (unnamed in GLSL): set through
                // `workgroup_spec_ids`, not by name.
            }
            Variable::SpecConstant { name, spec_id, ty } => {
                let kind = match ty {
                    Type::Scalar(ScalarType::Boolean) => SpecKind::Bool,
                    Type::Scalar(ScalarType::Integer {
                        is_signed: false, ..
                    }) => SpecKind::U32,
                    Type::Scalar(ScalarType::Integer {
                        is_signed: true, ..
                    }) => SpecKind::I32,
                    Type::Scalar(ScalarType::Float { .. }) => SpecKind::F32,
                    other => {
                        return Err(format!(
                            "specialization constant of type {other:?} is not supported"
                        ));
                    }
                };
                let name = name
                    .clone()
                    .ok_or(format!("specialization constant {spec_id} has no name"))?;
                spec_constants.push(SpecConstant {
                    name,
                    id: *spec_id,
                    kind,
                });
            }
            Variable::Input { .. } | Variable::Output { .. } => {}
        }
    }
    bindings.sort_by_key(|b| (b.set, b.binding));
    for pair in bindings.windows(2) {
        if (pair[0].set, pair[0].binding) == (pair[1].set, pair[1].binding) {
            return Err(format!(
                "set {} binding {} is declared twice",
                pair[0].set, pair[0].binding
            ));
        }
    }
    spec_constants.sort_by_key(|s| s.id);
    Ok(ReflectedEntry {
        name: shader.name.clone(),
        source: shader.source.clone(),
        entry_point: entry.name.clone(),
        workgroup_size,
        workgroup_spec_ids,
        bindings,
        push_constant_bytes,
        spec_constants,
    })
}
