//! Clustering 10, 50 and 200 contacts into 5 clusters, cold and warm (goal: 50 → 5 warm < 5 µs).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{Contact, ContactSet, Real, Vec3};

/// A contact patch like a spoon on a cup wall: points on a 2 cm × 1 cm curved strip, drifting by
/// 10 µm per frame, depths varying smoothly.
fn frame(t: usize, n: usize) -> Vec<Contact> {
    (0..n)
        .map(|i| {
            let u = (i as Real * 0.618_034).fract();
            let v = (i as Real * 0.414_214).fract();
            let x = 0.02 * u + 1e-5 * t as Real;
            let y = 0.01 * v;
            let p = Vec3::new(x, y, 0.002 * (30.0 * x).sin());
            let n = Vec3::new(-0.06 * (30.0 * x).cos(), 0.0, 1.0).normalize();
            let d = 3e-4 * (1.0 + (200.0 * x + 100.0 * y).sin());
            Contact::new(p, p, p - d * n, n, d).unwrap()
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("cluster");
    for n in [10usize, 50, 200] {
        let frames: Vec<Vec<Contact>> = (0..64).map(|t| frame(t, n)).collect();
        for warm in [false, true] {
            let name = format!("{n}_{}", if warm { "warm" } else { "cold" });
            let mut clusterer = Clusterer::new(ClusterParams {
                warm_start: warm,
                ..Default::default()
            })
            .unwrap();
            let mut reps = ContactSet::with_capacity(8);
            let mut t = 0;
            group.bench_function(&name, |b| {
                b.iter(|| {
                    t = (t + 1) % frames.len();
                    clusterer
                        .cluster(black_box(&frames[t]), 1e-3, &mut reps)
                        .unwrap()
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
