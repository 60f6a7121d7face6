//! The driver compiler's own statistics of a pipeline (VK_KHR_pipeline_executable_properties):
//! for Intel's ANV the SIMD width, instruction count, loops, cycle estimate, spills and fills,
//! sends, GRF registers and scratch size of each executable; other drivers report their own
//! sets (NVIDIA: registers, binary size; RADV: VGPRs, SGPRs, LDS, waves).
//!
//! Decisions:
//! - Statistics are kept as the driver names them (name, description, value), in its order;
//!   nothing here knows one driver's vocabulary. Readers that want, say, spills look the name up
//!   ([`Executable::value`]).
//! - Only a device created with `DeviceConfig::pipeline_statistics` on a driver that has the
//!   extension captures statistics; elsewhere [`ComputePipeline::executables`] says None, so a
//!   caller can print one line saying the driver has none.

use super::error::{GpuResult, vk_err};
use super::pipeline::ComputePipeline;
use ash::vk;

/// A statistic's value, typed as the driver gives it.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(untagged)]
pub enum StatValue {
    /// A boolean.
    Bool(bool),
    /// A signed integer.
    Int(i64),
    /// An unsigned integer.
    Uint(u64),
    /// A floating-point number.
    Float(f64),
}

impl StatValue {
    /// The value as a number (booleans as 0/1).
    pub fn as_f64(self) -> f64 {
        match self {
            StatValue::Bool(b) => b as u8 as f64,
            StatValue::Int(v) => v as f64,
            StatValue::Uint(v) => v as f64,
            StatValue::Float(v) => v,
        }
    }
}

/// One statistic.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Statistic {
    /// The driver's short name ("Instruction Count", "SIMD Width", "Spill Count", ...).
    pub name: String,
    /// The driver's description.
    pub description: String,
    /// Its value.
    pub value: StatValue,
}

/// One executable of a pipeline (a compute pipeline has one per compiled dispatch width the
/// driver keeps; ANV usually one).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Executable {
    /// The driver's name for it ("SIMD16 Compute Shader").
    pub name: String,
    /// The driver's description.
    pub description: String,
    /// Subgroup size it runs with.
    pub subgroup_size: u32,
    /// Its statistics, in the driver's order.
    pub statistics: Vec<Statistic>,
}

impl Executable {
    /// The value of the statistic named `name` (exactly as the driver names it).
    pub fn value(&self, name: &str) -> Option<StatValue> {
        self.statistics
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.value)
    }
}

fn text(chars: &[std::ffi::c_char]) -> String {
    let bytes: Vec<u8> = chars
        .iter()
        .take_while(|&&c| c != 0)
        .map(|&c| c as u8)
        .collect();
    String::from_utf8_lossy(&bytes).into_owned()
}

fn value(statistic: &vk::PipelineExecutableStatisticKHR) -> StatValue {
    // SAFETY: the union member read is the one `format` says the driver wrote.
    unsafe {
        match statistic.format {
            vk::PipelineExecutableStatisticFormatKHR::BOOL32 => {
                StatValue::Bool(statistic.value.b32 != vk::FALSE)
            }
            vk::PipelineExecutableStatisticFormatKHR::INT64 => StatValue::Int(statistic.value.i64),
            vk::PipelineExecutableStatisticFormatKHR::FLOAT64 => {
                StatValue::Float(statistic.value.f64)
            }
            _ => StatValue::Uint(statistic.value.u64),
        }
    }
}

impl ComputePipeline {
    /// The driver's executables of this pipeline with their statistics; None when the device
    /// captures none (created without `pipeline_statistics`, or a driver without the
    /// extension).
    pub fn executables(&self) -> GpuResult<Option<Vec<Executable>>> {
        let Some(loader) = &self.device.executable_properties else {
            return Ok(None);
        };
        let info = vk::PipelineInfoKHR::default().pipeline(self.raw);
        // SAFETY: a pipeline of this device, created with CAPTURE_STATISTICS_KHR.
        let properties = unsafe { loader.get_pipeline_executable_properties(&info) }
            .map_err(vk_err("vkGetPipelineExecutablePropertiesKHR"))?;
        let mut executables = Vec::with_capacity(properties.len());
        for (index, p) in properties.iter().enumerate() {
            let executable = vk::PipelineExecutableInfoKHR::default()
                .pipeline(self.raw)
                .executable_index(index as u32);
            // SAFETY: as above, with an index the driver just reported.
            let statistics = unsafe { loader.get_pipeline_executable_statistics(&executable) }
                .map_err(vk_err("vkGetPipelineExecutableStatisticsKHR"))?;
            executables.push(Executable {
                name: text(&p.name),
                description: text(&p.description),
                subgroup_size: p.subgroup_size,
                statistics: statistics
                    .iter()
                    .map(|s| Statistic {
                        name: text(&s.name),
                        description: text(&s.description),
                        value: value(s),
                    })
                    .collect(),
            });
        }
        Ok(Some(executables))
    }
}
