//! After warm-up, clustering allocates nothing (counted with a global allocator).
// A counting global allocator needs `unsafe impl GlobalAlloc`; it only forwards to `System`.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{Contact, ContactSet, Real, Vec3};

struct Counting;
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn frame(t: usize, n: usize) -> Vec<Contact> {
    (0..n)
        .map(|i| {
            let a = i as Real * 0.37 + 1e-3 * t as Real;
            let p = Vec3::new(0.02 * a.cos(), 0.01 * (2.0 * a).sin(), 0.0);
            Contact::new(p, p, p, Vec3::z(), 1e-4 * (1.0 + a.sin())).unwrap()
        })
        .collect()
}

#[test]
fn clustering_allocates_nothing_after_warm_up() {
    let frames: Vec<Vec<Contact>> = (0..200).map(|t| frame(t, 20 + (t * 7) % 180)).collect();
    let mut clusterer = Clusterer::new(ClusterParams::default()).unwrap();
    let mut reps = ContactSet::with_capacity(8);
    // Warm up with the largest contact count.
    clusterer.cluster(&frame(0, 200), 1e-3, &mut reps).unwrap();
    let before = ALLOCATIONS.load(Ordering::Relaxed);
    for f in &frames {
        clusterer.cluster(f, 1e-3, &mut reps).unwrap();
    }
    let after = ALLOCATIONS.load(Ordering::Relaxed);
    assert_eq!(after - before, 0, "clustering allocated after warm-up");
    assert_eq!(reps.len(), 5);
}
