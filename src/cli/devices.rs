//! `morphray devices`: every Vulkan device, and why any cannot run morphray.

use super::output::print_line;
use crate::error::Error;
use crate::gpu::adapter::enumerate;
use crate::gpu::instance::{Instance, Validation};

/// Runs the command.
pub fn run() -> Result<(), Error> {
    let instance = Instance::new(Validation::Off)?;
    let adapters = enumerate(&instance)?;
    if adapters.is_empty() {
        return Err(crate::gpu::GpuError::NoDevices.into());
    }
    for (_, a) in adapters {
        let status = if a.is_suitable() {
            "usable".to_string()
        } else {
            format!("rejected: {}", a.rejections.join("; "))
        };
        print_line(&format!(
            "#{} {} ({}, {}, subgroup {}): {status}",
            a.index,
            a.name,
            a.type_name(),
            a.driver,
            a.subgroup_size
        ));
    }
    Ok(())
}
