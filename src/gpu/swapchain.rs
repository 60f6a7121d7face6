//! The window's Vulkan surface and swapchain: creation, recreation on resize, minimize
//! handling, acquire and present.
//!
//! Decisions:
//! - The swapchain is only ever a copy destination: the frame (raymarch + interface) is
//!   composed in an image the viewer owns (`painter.rs`) and blitted in, so screenshots and
//!   the offscreen mode read the same pixels the window shows, and the swapchain needs no
//!   usage beyond TRANSFER_DST (checked against the surface's capabilities).
//! - A UNORM format (B8G8R8A8 or R8G8B8A8) is preferred: the raymarch writes display values
//!   and egui blends in gamma space, so an sRGB swapchain would re-encode them and brighten
//!   the picture relative to `morphray render`'s PNGs.
//! - Vsync (FIFO, always available) by default; without it MAILBOX, else IMMEDIATE.
//! - One acquire semaphore per frame in flight (reused only after that frame's fence), one
//!   "rendered" semaphore per swapchain image (a present may still wait on it after the fence).
//! - A zero-sized window (minimized) has no swapchain; frames are skipped until it has a size.
//! - Recreation is the one place that waits for the queue to go idle (`vkQueueWaitIdle`, never
//!   `vkDeviceWaitIdle`): without VK_EXT_swapchain_maintenance1 nothing else says when a present
//!   finished using the old swapchain's images and semaphores. It happens only on resize.

use super::FRAMES_IN_FLIGHT;
use super::error::vk_err;
use super::{Device, GpuError, GpuResult};
use ash::khr;
use ash::vk;
use raw_window_handle::{HasDisplayHandle, HasWindowHandle};
use std::sync::Arc;

/// The window's surface.
pub struct Surface {
    loader: khr::surface::Instance,
    raw: vk::SurfaceKHR,
    // Keeps the instance alive until the surface is destroyed.
    _device: Device,
}

impl Surface {
    /// Creates the surface of `window` and checks that the device's queue can present to it.
    pub fn new(
        device: &Device,
        window: &(impl HasDisplayHandle + HasWindowHandle),
    ) -> GpuResult<Surface> {
        let display = window
            .display_handle()
            .map_err(|e| GpuError::Unsupported(format!("no display handle: {e}")))?;
        let handle = window
            .window_handle()
            .map_err(|e| GpuError::Unsupported(format!("no window handle: {e}")))?;
        let instance = device.instance();
        // SAFETY: the handles come from a live window; the instance was created with the
        // extensions ash-window reported for this display.
        let raw = unsafe {
            ash_window::create_surface(
                instance.entry(),
                instance.raw(),
                display.as_raw(),
                handle.as_raw(),
                None,
            )
        }
        .map_err(vk_err("vkCreate*SurfaceKHR"))?;
        let loader = khr::surface::Instance::new(instance.entry(), instance.raw());
        let surface = Surface {
            loader,
            raw,
            _device: device.clone(),
        };
        // SAFETY: a query on the device's physical device and this surface.
        let supported = unsafe {
            surface.loader.get_physical_device_surface_support(
                device.physical(),
                device.adapter().queue_family,
                raw,
            )
        }
        .map_err(vk_err("vkGetPhysicalDeviceSurfaceSupportKHR"))?;
        if !supported {
            return Err(GpuError::Unsupported(format!(
                "{} cannot present to this window from its compute queue (try --offscreen)",
                device.adapter().name
            )));
        }
        Ok(surface)
    }
}

impl Drop for Surface {
    fn drop(&mut self) {
        // SAFETY: every swapchain holds an Arc of this surface, so none is left; the instance
        // is alive (held through `_device`, whose field is dropped after this runs).
        unsafe { self.loader.destroy_surface(self.raw, None) };
    }
}

/// The preferred surface format: a UNORM 8-bit RGBA/BGRA in the sRGB colour space.
pub fn choose_format(formats: &[vk::SurfaceFormatKHR]) -> Option<vk::SurfaceFormatKHR> {
    let preferred = [vk::Format::B8G8R8A8_UNORM, vk::Format::R8G8B8A8_UNORM];
    preferred
        .iter()
        .find_map(|f| {
            formats
                .iter()
                .find(|s| s.format == *f && s.color_space == vk::ColorSpaceKHR::SRGB_NONLINEAR)
        })
        .or_else(|| formats.first())
        .copied()
}

/// FIFO with vsync; otherwise MAILBOX, IMMEDIATE, or FIFO as the last resort.
pub fn choose_present_mode(modes: &[vk::PresentModeKHR], vsync: bool) -> vk::PresentModeKHR {
    if vsync {
        return vk::PresentModeKHR::FIFO;
    }
    [vk::PresentModeKHR::MAILBOX, vk::PresentModeKHR::IMMEDIATE]
        .into_iter()
        .find(|m| modes.contains(m))
        .unwrap_or(vk::PresentModeKHR::FIFO)
}

/// The swapchain extent for a window of `size` pixels, or None when it has no area
/// (minimized): the surface's current extent when it dictates one, else `size` clamped.
pub fn choose_extent(caps: &vk::SurfaceCapabilitiesKHR, size: [u32; 2]) -> Option<vk::Extent2D> {
    let extent = if caps.current_extent.width != u32::MAX {
        caps.current_extent
    } else {
        vk::Extent2D {
            width: size[0].clamp(caps.min_image_extent.width, caps.max_image_extent.width),
            height: size[1].clamp(caps.min_image_extent.height, caps.max_image_extent.height),
        }
    };
    (extent.width > 0 && extent.height > 0 && size[0] > 0 && size[1] > 0).then_some(extent)
}

/// An acquired image to draw into.
#[derive(Clone, Copy, Debug)]
pub struct Acquired {
    /// Index in the swapchain.
    pub index: u32,
    /// The image.
    pub image: vk::Image,
    /// Its size.
    pub extent: vk::Extent2D,
    /// Wait for this (at the transfer stage) before writing the image.
    pub wait: vk::Semaphore,
    /// Signal this when the frame is done; the present waits for it.
    pub signal: vk::Semaphore,
}

/// The swapchain.
pub struct Swapchain {
    loader: khr::swapchain::Device,
    raw: vk::SwapchainKHR,
    images: Vec<vk::Image>,
    /// Current size in pixels.
    pub extent: vk::Extent2D,
    /// Chosen format.
    pub format: vk::Format,
    /// Chosen present mode.
    pub present_mode: vk::PresentModeKHR,
    acquire: [vk::Semaphore; FRAMES_IN_FLIGHT],
    rendered: Vec<vk::Semaphore>,
    vsync: bool,
    surface: Arc<Surface>,
    device: Device,
}

impl Swapchain {
    /// Creates a swapchain for a window of `size` pixels; None while it has no area.
    pub fn new(
        device: &Device,
        surface: Arc<Surface>,
        size: [u32; 2],
        vsync: bool,
    ) -> GpuResult<Option<Swapchain>> {
        let loader = khr::swapchain::Device::new(device.instance().raw(), device.raw());
        let mut acquire = [vk::Semaphore::null(); FRAMES_IN_FLIGHT];
        for s in &mut acquire {
            *s = new_semaphore(device)?;
        }
        let mut swapchain = Swapchain {
            loader,
            raw: vk::SwapchainKHR::null(),
            images: Vec::new(),
            extent: vk::Extent2D::default(),
            format: vk::Format::UNDEFINED,
            present_mode: vk::PresentModeKHR::FIFO,
            acquire,
            rendered: Vec::new(),
            vsync,
            surface,
            device: device.clone(),
        };
        Ok(swapchain.recreate(size)?.then_some(swapchain))
    }

    /// Rebuilds the swapchain for a window of `size` pixels (after a resize or an out-of-date
    /// present); false while the window has no area (nothing to draw into).
    pub fn recreate(&mut self, size: [u32; 2]) -> GpuResult<bool> {
        let surface = &self.surface;
        let physical = self.device.physical();
        // SAFETY: queries on a live surface of this device's instance.
        let (caps, formats, modes) = unsafe {
            (
                surface
                    .loader
                    .get_physical_device_surface_capabilities(physical, surface.raw)
                    .map_err(vk_err("vkGetPhysicalDeviceSurfaceCapabilitiesKHR"))?,
                surface
                    .loader
                    .get_physical_device_surface_formats(physical, surface.raw)
                    .map_err(vk_err("vkGetPhysicalDeviceSurfaceFormatsKHR"))?,
                surface
                    .loader
                    .get_physical_device_surface_present_modes(physical, surface.raw)
                    .map_err(vk_err("vkGetPhysicalDeviceSurfacePresentModesKHR"))?,
            )
        };
        let Some(extent) = choose_extent(&caps, size) else {
            return Ok(false);
        };
        let format = choose_format(&formats)
            .ok_or_else(|| GpuError::Unsupported("the window surface offers no format".into()))?;
        if !caps
            .supported_usage_flags
            .contains(vk::ImageUsageFlags::TRANSFER_DST)
        {
            return Err(GpuError::Unsupported(
                "the window surface cannot be a copy destination (TRANSFER_DST)".into(),
            ));
        }
        let blit_dst = self
            .device
            .supports_format(format.format, vk::FormatFeatureFlags::BLIT_DST);
        if !blit_dst {
            return Err(GpuError::Unsupported(format!(
                "the window's format {:?} cannot be a blit destination",
                format.format
            )));
        }
        let present_mode = choose_present_mode(&modes, self.vsync);
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        let old = self.raw;
        if old != vk::SwapchainKHR::null() {
            // The one idle wait (module docs): presents of the old swapchain must be done
            // before its images and the per-image semaphores go away.
            self.device
                .with_queue(|queue| {
                    // SAFETY: the queue is locked by with_queue.
                    unsafe { self.device.raw().queue_wait_idle(queue) }
                })?
                .map_err(vk_err("vkQueueWaitIdle"))?;
        }
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(surface.raw)
            .min_image_count(count)
            .image_format(format.format)
            .image_color_space(format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(vk::ImageUsageFlags::TRANSFER_DST)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
            .present_mode(present_mode)
            .clipped(true)
            .old_swapchain(old);
        // SAFETY: valid create info on a live surface; the old swapchain is retired by it.
        let raw = unsafe { self.loader.create_swapchain(&info, None) }
            .map_err(vk_err("vkCreateSwapchainKHR"))?;
        if old != vk::SwapchainKHR::null() {
            // SAFETY: the queue is idle, so nothing uses the old swapchain or its semaphores.
            unsafe { self.loader.destroy_swapchain(old, None) };
        }
        self.raw = raw;
        for s in self.rendered.drain(..) {
            // SAFETY: idle queue (above) or never used.
            unsafe { self.device.raw().destroy_semaphore(s, None) };
        }
        // SAFETY: a live swapchain.
        self.images = unsafe { self.loader.get_swapchain_images(raw) }
            .map_err(vk_err("vkGetSwapchainImagesKHR"))?;
        for _ in 0..self.images.len() {
            let s = new_semaphore(&self.device)?;
            self.rendered.push(s);
        }
        self.extent = extent;
        self.format = format.format;
        self.present_mode = present_mode;
        Ok(true)
    }

    /// Acquires the next image for frame slot `slot`; None when the swapchain is out of date
    /// (recreate and skip the frame).
    pub fn acquire(&mut self, slot: usize) -> GpuResult<Option<Acquired>> {
        let wait = self.acquire[slot % FRAMES_IN_FLIGHT];
        // SAFETY: the semaphore is unsignalled: the frame that last waited on it has finished
        // (the caller waited for that slot's fence).
        let result = unsafe {
            self.loader
                .acquire_next_image(self.raw, u64::MAX, wait, vk::Fence::null())
        };
        match result {
            Ok((index, _suboptimal)) => Ok(Some(Acquired {
                index,
                image: self.images[index as usize],
                extent: self.extent,
                wait,
                signal: self.rendered[index as usize],
            })),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(None),
            Err(e) => Err(GpuError::from_vk("vkAcquireNextImageKHR", e)),
        }
    }

    /// Presents an acquired image; true when the swapchain should be recreated.
    pub fn present(&self, acquired: &Acquired) -> GpuResult<bool> {
        let swapchains = [self.raw];
        let indices = [acquired.index];
        let waits = [acquired.signal];
        let info = vk::PresentInfoKHR::default()
            .wait_semaphores(&waits)
            .swapchains(&swapchains)
            .image_indices(&indices);
        let result = self.device.with_queue(|queue| {
            // SAFETY: the queue is locked; the image was acquired and its frame submitted.
            unsafe { self.loader.queue_present(queue, &info) }
        })?;
        match result {
            Ok(suboptimal) => Ok(suboptimal),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(true),
            Err(e) => Err(GpuError::from_vk("vkQueuePresentKHR", e)),
        }
    }
}

impl Drop for Swapchain {
    fn drop(&mut self) {
        // Shutdown (or a device loss): wait for the queue so presents are done with the images
        // and semaphores; errors here leave nothing better to do than proceed.
        let _ = self.device.with_queue(|queue| {
            // SAFETY: the queue is locked.
            unsafe { self.device.raw().queue_wait_idle(queue) }
        });
        // SAFETY: the queue is idle.
        unsafe {
            for s in self.rendered.drain(..).chain(self.acquire) {
                self.device.raw().destroy_semaphore(s, None);
            }
            if self.raw != vk::SwapchainKHR::null() {
                self.loader.destroy_swapchain(self.raw, None);
            }
        }
    }
}

fn new_semaphore(device: &Device) -> GpuResult<vk::Semaphore> {
    // SAFETY: valid create info on a live device.
    unsafe {
        device
            .raw()
            .create_semaphore(&vk::SemaphoreCreateInfo::default(), None)
    }
    .map_err(vk_err("vkCreateSemaphore"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn formats_prefer_unorm_and_modes_follow_vsync() {
        let f = |format| vk::SurfaceFormatKHR {
            format,
            color_space: vk::ColorSpaceKHR::SRGB_NONLINEAR,
        };
        let offered = [f(vk::Format::B8G8R8A8_SRGB), f(vk::Format::B8G8R8A8_UNORM)];
        assert_eq!(
            choose_format(&offered).unwrap().format,
            vk::Format::B8G8R8A8_UNORM
        );
        assert_eq!(
            choose_format(&[f(vk::Format::R5G6B5_UNORM_PACK16)])
                .unwrap()
                .format,
            vk::Format::R5G6B5_UNORM_PACK16
        );
        assert!(choose_format(&[]).is_none());
        let modes = [vk::PresentModeKHR::FIFO, vk::PresentModeKHR::IMMEDIATE];
        assert_eq!(choose_present_mode(&modes, true), vk::PresentModeKHR::FIFO);
        assert_eq!(
            choose_present_mode(&modes, false),
            vk::PresentModeKHR::IMMEDIATE
        );
        assert_eq!(
            choose_present_mode(&[vk::PresentModeKHR::FIFO], false),
            vk::PresentModeKHR::FIFO
        );
    }

    #[test]
    fn a_minimized_window_has_no_extent() {
        let mut caps = vk::SurfaceCapabilitiesKHR {
            current_extent: vk::Extent2D {
                width: u32::MAX,
                height: u32::MAX,
            },
            min_image_extent: vk::Extent2D {
                width: 1,
                height: 1,
            },
            max_image_extent: vk::Extent2D {
                width: 4096,
                height: 4096,
            },
            ..Default::default()
        };
        assert_eq!(
            choose_extent(&caps, [640, 480]),
            Some(vk::Extent2D {
                width: 640,
                height: 480
            })
        );
        assert_eq!(choose_extent(&caps, [0, 480]), None);
        caps.current_extent = vk::Extent2D {
            width: 0,
            height: 0,
        };
        assert_eq!(
            choose_extent(&caps, [640, 480]),
            None,
            "X11 reports 0x0 when minimized"
        );
        caps.current_extent = vk::Extent2D {
            width: 800,
            height: 600,
        };
        assert_eq!(choose_extent(&caps, [640, 480]).unwrap().width, 800);
    }
}
