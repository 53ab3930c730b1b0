//! After warm-up, clustering allocates nothing (counted with a global allocator).
use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{Contact, ContactSet};
use haptic_test_support::alloc::{CountingAllocator, allocations};
use haptic_test_support::contacts::drifting_patch;

#[global_allocator]
static GLOBAL: CountingAllocator = CountingAllocator;

#[test]
fn clustering_allocates_nothing_after_warm_up() {
    let frames: Vec<Vec<Contact>> = (0..200)
        .map(|t| drifting_patch(t, 20 + (t * 7) % 180))
        .collect();
    let mut clusterer = Clusterer::new(ClusterParams::default()).unwrap();
    let mut reps = ContactSet::with_capacity(16);
    // Warm up with the largest contact count.
    clusterer
        .cluster(&drifting_patch(0, 200), 1e-3, &mut reps)
        .unwrap();
    let before = allocations();
    for f in &frames {
        clusterer.cluster(f, 1e-3, &mut reps).unwrap();
    }
    let after = allocations();
    assert_eq!(after - before, 0, "clustering allocated after warm-up");
    // Five clusters, each a torque pair.
    assert_eq!(reps.len(), 10);
}
