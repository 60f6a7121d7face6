//! Internal faults that happen where no caller can be handed an error: in destructors (a failed
//! free, a pool that would not reset, a poisoned lock while releasing).
//!
//! Decision (issue 13 item 6): such a fault is recorded here, per device, never skipped;
//! [`super::Device::internal_faults`] returns them, and tests assert the list is empty after
//! their GPU work, as they do for validation errors. Where a caller is waiting for a result the
//! fault is returned instead, as [`super::GpuError::Internal`]. The log itself recovers from a
//! poisoned lock (a `Vec<String>` cannot be left half-updated by a panic), so reporting a fault
//! can never fail.

use super::error::GpuError;
use std::sync::Mutex;

/// Internal faults recorded on one device.
#[derive(Debug, Default)]
pub struct FaultLog {
    faults: Mutex<Vec<String>>,
}

impl FaultLog {
    /// Records `fault` (its one-line message).
    pub fn record(&self, fault: &GpuError) {
        let mut list = self.faults.lock().unwrap_or_else(|p| p.into_inner());
        list.push(fault.to_string());
    }

    /// Every fault so far, oldest first.
    pub fn all(&self) -> Vec<String> {
        self.faults
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faults_are_kept_even_after_a_panic_poisoned_the_log() {
        let log = std::sync::Arc::new(FaultLog::default());
        log.record(&GpuError::Internal("first".into()));
        let poisoner = log.clone();
        let _ = std::thread::spawn(move || {
            let _guard = poisoner.faults.lock();
            panic!("poison the log");
        })
        .join();
        log.record(&GpuError::Internal("second".into()));
        let all = log.all();
        assert_eq!(all.len(), 2);
        assert!(all[1].contains("second"), "{all:?}");
    }
}
