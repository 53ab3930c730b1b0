//! A global allocator that counts allocations, to check that a loop allocates nothing.
//!
//! ```ignore
//! use haptic_test_support::alloc::{CountingAllocator, allocations};
//!
//! #[global_allocator]
//! static GLOBAL: CountingAllocator = CountingAllocator;
//!
//! let before = allocations();
//! // ... the code that must not allocate ...
//! assert_eq!(allocations() - before, 0);
//! ```

// A counting global allocator needs `unsafe impl GlobalAlloc`; it only forwards to `System`.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Allocations by this thread (a const-initialized `Cell`: reading it never allocates).
    static THREAD_ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

/// Counts one allocation, in the process's total and in the calling thread's.
#[inline]
fn count() {
    ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
    // `try_with`: a thread being torn down may still allocate after its locals are gone.
    let _ = THREAD_ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
}

/// Forwards to [`System`] and counts every allocation and reallocation (not deallocations).
/// Install it with `#[global_allocator]` in the test binary that measures.
pub struct CountingAllocator;

// SAFETY: every method forwards to `System` with the caller's arguments unchanged.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        // SAFETY: as `GlobalAlloc::alloc`, the caller's contract.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by `System` through this allocator with `layout`.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        // SAFETY: as `GlobalAlloc::realloc`, the caller's contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Allocations (and reallocations) counted so far, by every thread of the process.
pub fn allocations() -> usize {
    ALLOCATIONS.load(Ordering::Relaxed)
}

/// Allocations (and reallocations) counted so far by the calling thread: what a loop run on
/// this thread allocates, whatever other threads of the process (a test harness's) do meanwhile.
pub fn thread_allocations() -> usize {
    THREAD_ALLOCATIONS.with(Cell::get)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicBool;
    use std::sync::{Arc, Barrier};

    #[global_allocator]
    static GLOBAL: CountingAllocator = CountingAllocator;

    /// A vector allocated here counts on this thread; another thread's, only in the total.
    #[test]
    fn counts_the_calling_threads_allocations() {
        let before = thread_allocations();
        let v: Vec<u8> = Vec::with_capacity(16);
        std::hint::black_box(&v);
        assert_eq!(thread_allocations() - before, 1);

        let go = Arc::new(Barrier::new(2));
        let done = Arc::new(AtomicBool::new(false));
        let other = {
            let (go, done) = (go.clone(), done.clone());
            std::thread::spawn(move || {
                go.wait();
                for n in 1..100 {
                    std::hint::black_box(vec![0u8; n]);
                }
                done.store(true, Ordering::Release);
            })
        };
        let (mine, total) = (thread_allocations(), allocations());
        go.wait();
        while !done.load(Ordering::Acquire) {
            std::hint::spin_loop();
        }
        assert_eq!(thread_allocations(), mine);
        assert!(allocations() - total >= 99);
        other.join().unwrap();
    }
}
