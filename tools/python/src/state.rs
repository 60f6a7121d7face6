//! The process-wide engine: one device per process, shared by every volume.
//!
//! Decisions:
//! - The engine is created on first use (opening a volume), with the configuration that
//!   `configure()` set (device, memory budget, validation); a later `configure()` with another
//!   configuration drops it, and volumes opened on the old engine then refuse to render (their
//!   GPU data lives on the old device) with a message that says to open them again.
//! - One render target is kept for the last image size, so a notebook rendering a series of
//!   frames of one size allocates it once.
//! - A poisoned mutex (a panic inside the engine) is recovered: the state is plain data and the
//!   next call either works or reports the engine's own error.

use crate::errors;
use morphray::engine::{Engine, EngineConfig, RenderTarget};
use morphray::gpu::{DeviceConfig, DeviceSelector, Validation};
use pyo3::prelude::*;
use std::sync::{Mutex, MutexGuard};

/// What `configure()` sets.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Settings {
    /// Device selector (index or name substring, as `--device`); None: the default choice.
    pub device: Option<String>,
    /// GPU memory budget in bytes; None: what the device allows.
    pub memory_budget: Option<u64>,
    /// Require the Vulkan validation layer.
    pub validation: bool,
}

impl Settings {
    fn engine_config(&self) -> EngineConfig {
        EngineConfig {
            memory_budget: self.memory_budget,
            device: DeviceConfig {
                selector: self
                    .device
                    .as_deref()
                    .map(DeviceSelector::parse)
                    .unwrap_or_default(),
                validation: if self.validation {
                    Validation::Required
                } else {
                    Validation::from_build_and_env()
                },
                ..DeviceConfig::default()
            },
            ..EngineConfig::default()
        }
    }
}

/// The process-wide state.
pub struct State {
    pub settings: Settings,
    pub engine: Option<Engine>,
    /// Incremented each time the engine is replaced; volumes remember the one they were opened on.
    pub generation: u64,
    /// The render target of the last image size.
    pub target: Option<([u32; 2], RenderTarget)>,
}

static STATE: Mutex<State> = Mutex::new(State {
    settings: Settings {
        device: None,
        memory_budget: None,
        validation: false,
    },
    engine: None,
    generation: 0,
    target: None,
});

/// Locks the process-wide state.
pub fn lock() -> MutexGuard<'static, State> {
    STATE
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner())
}

impl State {
    /// The engine, created on first use; returns it with its generation.
    pub fn engine(&mut self) -> PyResult<(&mut Engine, u64)> {
        if self.engine.is_none() {
            let engine = Engine::new(self.settings.engine_config()).map_err(errors::gpu)?;
            self.engine = Some(engine);
        }
        let generation = self.generation;
        match self.engine.as_mut() {
            Some(engine) => Ok((engine, generation)),
            None => Err(errors::DeviceError::new_err(
                "the engine could not be created",
            )),
        }
    }

    /// The engine and a render target of `size`, for a volume opened on engine `generation`.
    pub fn engine_and_target(
        &mut self,
        generation: u64,
        size: [u32; 2],
    ) -> PyResult<(&mut Engine, &mut RenderTarget)> {
        if generation != self.generation || self.engine.is_none() {
            return Err(errors::Error::new_err(
                "this volume was opened before morphray.configure() changed the device or the \
                 memory budget; open it again",
            ));
        }
        if self.target.as_ref().is_none_or(|(s, _)| *s != size) {
            // The old target is freed before the new one is made.
            self.target = None;
            let engine = self.engine()?.0;
            let target = engine
                .render_target(size[0], size[1], ash::vk::Format::R8G8B8A8_UNORM)
                .map_err(errors::gpu)?;
            self.target = Some((size, target));
        }
        match (self.engine.as_mut(), self.target.as_mut()) {
            (Some(engine), Some((_, target))) => Ok((engine, target)),
            _ => Err(errors::DeviceError::new_err(
                "the engine could not be created",
            )),
        }
    }
}

/// Sets the device and the memory budget of the process's engine (see the module doc).
#[pyfunction]
#[pyo3(signature = (device=None, memory_budget=None, validation=false))]
pub fn configure(
    py: Python<'_>,
    device: Option<String>,
    memory_budget: Option<u64>,
    validation: bool,
) -> PyResult<()> {
    if memory_budget == Some(0) {
        return Err(errors::usage(
            "memory_budget must be a positive number of bytes",
        ));
    }
    let settings = Settings {
        device,
        memory_budget,
        validation,
    };
    py.detach(|| {
        let mut state = lock();
        if state.settings != settings {
            state.target = None;
            state.engine = None;
            state.generation += 1;
            state.settings = settings;
        }
    });
    Ok(())
}

/// The name of the device the engine runs on (starts the engine).
#[pyfunction]
pub fn device_name(py: Python<'_>) -> PyResult<String> {
    py.detach(|| {
        let mut state = lock();
        let (engine, _) = state.engine()?;
        Ok(engine.device().adapter().name.clone())
    })
}
