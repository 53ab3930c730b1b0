//! Clustering 10, 50 and 200 contacts into 5 clusters, cold and warm (goal: 50 → 5 warm < 5 µs),
//! with torque pairs (the default) and, warm, with one spring per cluster (the paper's model: the
//! peer that shows what the pairs cost).

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use haptic_cluster::{ClusterParams, Clusterer};
use haptic_core::{Contact, ContactSet};
use haptic_test_support::contacts::drifting_patch as frame;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("cluster");
    for n in [10usize, 50, 200] {
        let frames: Vec<Vec<Contact>> = (0..64).map(|t| frame(t, n)).collect();
        for (warm, pairs) in [(false, true), (true, false), (true, true)] {
            let name = format!(
                "{n}_{}{}",
                if warm { "warm" } else { "cold" },
                if pairs { "" } else { "_one_spring" }
            );
            let mut clusterer = Clusterer::new(ClusterParams {
                warm_start: warm,
                torque_pairs: pairs,
                ..Default::default()
            })
            .unwrap();
            let mut reps = ContactSet::with_capacity(16);
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
