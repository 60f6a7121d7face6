//! Reading GPU images and buffers back to the host (tests, the accuracy study, PNG output).
//!
//! Decision: readback is explicit and slow-path only: one submission that moves the image to
//! TRANSFER_SRC, copies it into host-readable memory, and moves it back to the access it had, so
//! the caller's view of the image's state stays true.

use crate::gpu::{Access, Buffer, BufferDesc, Device, GpuError, GpuResult, Image, Recording};
use ash::vk;
use std::sync::Arc;

/// Texels of an image decoded to f32, channels interleaved.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageData {
    /// Width, height, depth.
    pub extent: [u32; 3],
    /// Channels per texel.
    pub channels: usize,
    /// `extent product * channels` values, x fastest.
    pub values: Vec<f32>,
}

/// Bytes per texel and channel count of the formats the engine stores.
fn layout_of(format: vk::Format) -> GpuResult<(usize, usize)> {
    use vk::Format as F;
    Ok(match format {
        F::R8_UNORM | F::R8_SNORM => (1, 1),
        F::R8G8_SNORM => (2, 2),
        F::R16_UNORM | F::R16_SFLOAT => (2, 1),
        F::R32_SFLOAT => (4, 1),
        F::R16G16_SFLOAT => (4, 2),
        F::R32G32_SFLOAT => (8, 2),
        F::R8G8B8A8_SNORM | F::R8G8B8A8_UNORM => (4, 4),
        F::R16G16B16A16_SFLOAT => (8, 4),
        F::R32G32B32A32_SFLOAT => (16, 4),
        other => {
            return Err(GpuError::InvalidRequest(format!(
                "readback of {other:?} images is not supported"
            )));
        }
    })
}

/// Decodes tightly packed texels of `format` (SNORM as Vulkan defines it: max(c / 127, -1)).
pub fn decode(format: vk::Format, bytes: &[u8]) -> GpuResult<Vec<f32>> {
    use vk::Format as F;
    let u16s = || {
        bytes
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
    };
    Ok(match format {
        F::R8_UNORM | F::R8G8B8A8_UNORM => bytes.iter().map(|&b| b as f32 / 255.0).collect(),
        F::R8_SNORM | F::R8G8_SNORM | F::R8G8B8A8_SNORM => bytes
            .iter()
            .map(|&b| ((b as i8) as f32 / 127.0).max(-1.0))
            .collect(),
        F::R16_UNORM => u16s().map(|v| v as f32 / 65535.0).collect(),
        F::R16_SFLOAT | F::R16G16_SFLOAT | F::R16G16B16A16_SFLOAT => {
            u16s().map(|v| half::f16::from_bits(v).to_f32()).collect()
        }
        F::R32_SFLOAT | F::R32G32_SFLOAT | F::R32G32B32A32_SFLOAT => bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect(),
        other => {
            return Err(GpuError::InvalidRequest(format!(
                "readback of {other:?} images is not supported"
            )));
        }
    })
}

/// Reads the raw texel bytes of `image`, which was last accessed as `current`; the image is left
/// in `current` again.
pub fn read_image_bytes(
    device: &Device,
    image: &Arc<Image>,
    current: Access,
) -> GpuResult<Vec<u8>> {
    let (texel_bytes, _) = layout_of(image.format())?;
    let size = image.texel_count() * texel_bytes as u64;
    let readback = Buffer::new(device, readback_desc(image.name(), size))?;
    let mut rec = Recording::new(device, &format!("reading back {}", image.name()))?;
    // Orders the image's last use before the copy and moves it to TRANSFER_SRC.
    rec.barriers(&[], &[(image, current, Access::TransferRead)]);
    rec.copy_image_to_buffer(image, &readback);
    // Makes the copy visible to the host, and returns the image to the layout its owner expects.
    rec.barriers(
        &[(&readback, Access::TransferWrite, Access::HostRead)],
        &[(image, Access::TransferRead, current)],
    );
    rec.submit()?.wait()?;
    let mut bytes = vec![0u8; size as usize];
    readback.read(0, &mut bytes)?;
    Ok(bytes)
}

/// Reads and decodes `image` (see [`read_image_bytes`]).
pub fn read_image(device: &Device, image: &Arc<Image>, current: Access) -> GpuResult<ImageData> {
    let (_, channels) = layout_of(image.format())?;
    let bytes = read_image_bytes(device, image, current)?;
    Ok(ImageData {
        extent: image.extent(),
        channels,
        values: decode(image.format(), &bytes)?,
    })
}

/// The transient host buffer that `bytes` of the resource named `of` are read back through (as
/// [`read_buffer`] and [`read_image_bytes`] create it, and as the pass plan declares it).
pub fn readback_desc(of: &str, bytes: u64) -> BufferDesc {
    BufferDesc::readback(&format!("{of} (readback)"), bytes)
}

/// Copies the first `out.len()` bytes of a GPU buffer last written as `current` to the host.
pub fn read_buffer(
    device: &Device,
    buffer: &Arc<Buffer>,
    current: Access,
    out: &mut [u8],
) -> GpuResult<()> {
    let readback = Buffer::new(device, readback_desc(buffer.name(), out.len() as u64))?;
    let mut rec = Recording::new(device, &format!("reading back {}", buffer.name()))?;
    // Orders the buffer's last write before the copy.
    rec.barriers(&[(buffer, current, Access::TransferRead)], &[]);
    rec.copy_buffer(buffer, &readback, out.len() as u64);
    // Makes the copy visible to the host.
    rec.barriers(&[(&readback, Access::TransferWrite, Access::HostRead)], &[]);
    rec.submit()?.wait()?;
    readback.read(0, out)
}
