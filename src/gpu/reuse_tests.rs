//! Tests of per-queue reuse (`recycler.rs`) and of descriptor-pool reuse
//! (`descriptor_pools.rs`), on a real device with the validation layer required: a lease is
//! reused only after its fence was waited on, never while in flight, and everything it holds is
//! fresh (timestamps, breadcrumbs) when it records again.

use super::recycler::{CRUMB_BUFFER_BYTES, CRUMB_SLOTS, MAX_FREE};
use super::shaders::table;
use super::{
    Access, Buffer, BufferDesc, ComputePipeline, DescriptorSet, Device, DeviceConfig, Recording,
    Resource, Validation,
};
use ash::vk;
use std::sync::Arc;

fn device() -> Device {
    let config = DeviceConfig {
        validation: Validation::Required,
        ..Default::default()
    };
    Device::new(&config).unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device with the validation layer \
             (Debian: apt-get install mesa-vulkan-drivers libvulkan1 vulkan-validationlayers): {e}"
        )
    })
}

fn assert_clean(device: &Device) {
    let errors = device.validation_log().errors();
    assert!(
        errors.is_empty(),
        "validation errors:\n{}",
        errors.join("\n")
    );
    let faults = device.internal_faults();
    assert!(faults.is_empty(), "internal faults: {faults:?}");
}

/// A copy of 256 bytes through the bandwidth shader (a descriptor set and a dispatch), so the
/// recording does real work with a pass, timestamps and a breadcrumb.
fn copy_work(device: &Device, pipeline: &Arc<ComputePipeline>, rec: &mut Recording) {
    let source = Buffer::new(device, BufferDesc::gpu_storage("source", 256)).unwrap();
    let destination = Buffer::new(device, BufferDesc::gpu_storage("destination", 256)).unwrap();
    let set = DescriptorSet::new(
        pipeline,
        0,
        &[
            ("source", Resource::Buffer(source.clone())),
            ("destination", Resource::Buffer(destination)),
        ],
    )
    .unwrap();
    rec.fill_buffer(&source, 0, 256, 7);
    rec.barriers(
        &[(&source, Access::TransferWrite, Access::ComputeReadBuffer)],
        &[],
    );
    rec.begin_pass("copy");
    let params: [u32; 3] = [16, 1, 256];
    rec.dispatch(pipeline, &[set], bytemuck::cast_slice(&params), [1, 1, 1])
        .unwrap();
    rec.end_pass();
}

fn pipeline(device: &Device) -> Arc<ComputePipeline> {
    ComputePipeline::new(device, &table::BANDWIDTH, &[], vk::PipelineCache::null()).unwrap()
}

#[test]
fn a_lease_is_reused_after_its_wait_with_fresh_timestamps() {
    let device = device();
    let pipeline = pipeline(&device);
    let mut first = Recording::new(&device, "first").unwrap();
    let id = first.lease_id();
    copy_work(&device, &pipeline, &mut first);
    let timings = first.submit().unwrap().wait().unwrap();
    let counts = device.recycler_counts();
    assert_eq!((counts.created, counts.free), (1, 1), "{counts:?}");

    // The second recording gets the same pool back, and its pass is timed from its own queries
    // (one pass, not two).
    let mut second = Recording::new(&device, "second").unwrap();
    assert_eq!(second.lease_id(), id);
    copy_work(&device, &pipeline, &mut second);
    let again = second.submit().unwrap().wait().unwrap();
    assert_eq!(timings.len(), again.len());
    assert!(again.iter().all(|t| t.name == "copy" && t.gpu_ms >= 0.0));
    let counts = device.recycler_counts();
    assert_eq!((counts.created, counts.reused), (1, 1), "{counts:?}");
    assert_clean(&device);
}

#[test]
fn a_lease_in_flight_is_never_handed_out() {
    let device = device();
    let pipeline = pipeline(&device);
    let mut a = Recording::new(&device, "a").unwrap();
    copy_work(&device, &pipeline, &mut a);
    let a_id = a.lease_id();
    let in_flight = a.submit().unwrap();
    // While `a` may still run, a new recording gets a new lease.
    let b = Recording::new(&device, "b").unwrap();
    assert_ne!(b.lease_id(), a_id);
    assert_eq!(device.recycler_counts().free, 0);
    in_flight.wait().unwrap();
    assert_eq!(device.recycler_counts().free, 1);
    let c = Recording::new(&device, "c").unwrap();
    assert_eq!(c.lease_id(), a_id);
    drop((b, c));
    assert_eq!(device.recycler_counts().created, 2);
    assert_clean(&device);
}

#[test]
fn unsubmitted_recordings_and_unwaited_submissions_give_their_lease_back() {
    let device = device();
    let pipeline = pipeline(&device);
    let mut rec = Recording::new(&device, "dropped").unwrap();
    copy_work(&device, &pipeline, &mut rec);
    drop(rec);
    assert_eq!(device.recycler_counts().free, 1);
    let mut rec = Recording::new(&device, "submitted, not waited").unwrap();
    copy_work(&device, &pipeline, &mut rec);
    // Dropping the submission waits for its fence first, then gives the lease back.
    drop(rec.submit().unwrap());
    let counts = device.recycler_counts();
    assert_eq!((counts.created, counts.free), (1, 1), "{counts:?}");
    assert_clean(&device);
}

#[test]
fn the_free_list_is_bounded() {
    let device = device();
    let in_flight: Vec<_> = (0..MAX_FREE + 3)
        .map(|i| {
            Recording::new(&device, &format!("burst {i}"))
                .unwrap()
                .submit()
                .unwrap()
        })
        .collect();
    for submission in in_flight {
        submission.wait().unwrap();
    }
    let counts = device.recycler_counts();
    assert_eq!(counts.created, MAX_FREE as u64 + 3);
    assert_eq!((counts.free, counts.destroyed), (MAX_FREE, 3), "{counts:?}");
    // The leases share one breadcrumb buffer: one fixed allocation, whatever the burst.
    let live = device.ledger().live();
    assert_eq!(live.len(), 1, "{live:?}");
    assert_eq!(live[0].name, "pass breadcrumbs");
    assert!(live[0].bytes >= CRUMB_BUFFER_BYTES);
    assert_clean(&device);
}

#[test]
fn more_recordings_in_flight_than_breadcrumb_slots_still_run() {
    let device = device();
    let pipeline = pipeline(&device);
    let in_flight: Vec<_> = (0..CRUMB_SLOTS + 2)
        .map(|i| {
            let mut rec = Recording::new(&device, &format!("burst {i}")).unwrap();
            copy_work(&device, &pipeline, &mut rec);
            rec.submit().unwrap()
        })
        .collect();
    for submission in in_flight {
        assert_eq!(submission.wait().unwrap().len(), 1);
    }
    // Slots of destroyed leases are free again: a new lease gets one.
    let lease = device.shared.recycler.lease(&device.shared).unwrap();
    assert!(lease.crumbs.is_some());
    device
        .shared
        .recycler
        .give_back(&device.shared, lease)
        .unwrap();
    assert_clean(&device);
}

#[test]
fn descriptor_pools_are_reset_and_reused_once_their_set_is_done() {
    let device = device();
    let pipeline = pipeline(&device);
    let buffer = Buffer::new(&device, BufferDesc::gpu_storage("b", 256)).unwrap();
    let resources = [
        ("source", Resource::Buffer(buffer.clone())),
        ("destination", Resource::Buffer(buffer.clone())),
    ];
    let first = DescriptorSet::new(&pipeline, 0, &resources).unwrap();
    // Two sets alive at once need two pools.
    let second = DescriptorSet::new(&pipeline, 0, &resources).unwrap();
    assert_eq!(second.pools_created(), 2);
    drop((first, second));
    // Later sets reuse the two reset pools.
    for _ in 0..5 {
        let set = DescriptorSet::new(&pipeline, 0, &resources).unwrap();
        assert_eq!(set.pools_created(), 2);
    }
    // A set a submission holds is not given back until the submission is done.
    let mut rec = Recording::new(&device, "holds a set").unwrap();
    copy_work(&device, &pipeline, &mut rec);
    let submission = rec.submit().unwrap();
    let held = DescriptorSet::new(&pipeline, 0, &resources).unwrap();
    assert_eq!(held.pools_created(), 2, "one pool free, one held");
    let another = DescriptorSet::new(&pipeline, 0, &resources).unwrap();
    assert_eq!(another.pools_created(), 3, "the held pool was not reused");
    submission.wait().unwrap();
    drop((held, another));
    assert_clean(&device);
}

#[test]
fn a_reused_lease_has_zeroed_breadcrumbs_and_an_unsignalled_fence() {
    let device = device();
    let shared = &device.shared;
    let lease = shared.recycler.lease(shared).unwrap();
    // Work that finished every pass leaves its breadcrumbs set; a leftover 1 would make a later
    // device-lost error name the wrong pass.
    let mut rec = Recording::new(&device, "crumbs").unwrap();
    let pipeline = pipeline(&device);
    copy_work(&device, &pipeline, &mut rec);
    rec.submit().unwrap().wait().unwrap();
    shared.recycler.give_back(shared, lease).unwrap();
    let reused = shared.recycler.lease(shared).unwrap();
    let mut crumbs = [0xffu8; 8];
    reused.read_crumbs(&mut crumbs);
    assert_eq!(crumbs, [0; 8]);
    // SAFETY: a query on a live fence of this device.
    let signalled = unsafe { shared.raw.get_fence_status(reused.fence) }.unwrap();
    assert!(!signalled, "a leased fence must be unsignalled");
    shared.recycler.give_back(shared, reused).unwrap();
    assert_clean(&device);
}

#[test]
fn a_poisoned_allocator_is_an_internal_fault_reported_not_skipped() {
    // Issue 13 item 6: before, a free under a poisoned allocator lock was silently skipped and
    // an allocation reported as the caller's invalid request.
    let device = device();
    let buffer = Buffer::new(&device, BufferDesc::gpu_storage("victim", 256)).unwrap();
    let shared = device.shared.clone();
    let _ = std::thread::spawn(move || {
        let _guard = shared.allocator.lock();
        panic!("poison the allocator");
    })
    .join();
    drop(buffer);
    let faults = device.internal_faults();
    assert_eq!(faults.len(), 1, "{faults:?}");
    assert!(faults[0].contains("`victim` was not freed"), "{faults:?}");
    match Buffer::new(&device, BufferDesc::gpu_storage("next", 256)) {
        Err(super::GpuError::Internal(_)) => {}
        Err(other) => panic!("expected an internal fault, got {other}"),
        Ok(_) => panic!("expected an internal fault, got a buffer"),
    }
}
