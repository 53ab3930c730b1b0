//! Timing and accuracy study of `LodBackend` on the shared jaws (ignored by default; run with
//! `cargo test -p haptic-collision --release -- --ignored lod_jaws --nocapture`).

use std::time::Instant;

use haptic_collision::lod::LodBackend;
use haptic_collision::mesh::{DegeneratePolicy, LoadOptions, TriMesh};
use haptic_core::{CollisionBackend, ContactSet, Pose, QueryParams, Real, Vec3};
use nalgebra::UnitQuaternion;

const MESHES: &str = "/work/shared/meshes";

fn read_stl(path: &str, scale: Real) -> Option<TriMesh> {
    TriMesh::load(path, &LoadOptions::with_scale(scale))
        .ok()
        .map(|m| m.0)
}

/// Weighted k-means (K = 5, weights d + δ) and penalty wrench, as formulation.md defines them
/// (a stand-in for haptic-cluster and the penalty model, for this study only).
fn clustered_wrench(contacts: &ContactSet, delta: Real, tool_pos: &Vec3) -> [Real; 6] {
    let k_c = 5000.0;
    let cs: Vec<_> = contacts.iter().collect();
    if cs.is_empty() {
        return [0.0; 6];
    }
    let w: Vec<Real> = cs.iter().map(|c| (c.depth_m + delta).max(1e-12)).collect();
    let k = cs.len().min(5);
    let mut centres: Vec<Vec3> = vec![cs[0].p_a];
    while centres.len() < k {
        let far = cs
            .iter()
            .max_by(|a, b| {
                let da = centres
                    .iter()
                    .map(|c| (a.p_a - c).norm())
                    .fold(Real::INFINITY, Real::min);
                let db = centres
                    .iter()
                    .map(|c| (b.p_a - c).norm())
                    .fold(Real::INFINITY, Real::min);
                da.total_cmp(&db)
            })
            .unwrap();
        centres.push(far.p_a);
    }
    let mut assign = vec![0usize; cs.len()];
    for _ in 0..30 {
        for (i, c) in cs.iter().enumerate() {
            assign[i] = (0..k)
                .min_by(|&a, &b| {
                    (c.p_a - centres[a])
                        .norm()
                        .total_cmp(&(c.p_a - centres[b]).norm())
                })
                .unwrap();
        }
        for (j, centre) in centres.iter_mut().enumerate() {
            let (mut s, mut ws) = (Vec3::zeros(), 0.0);
            for i in 0..cs.len() {
                if assign[i] == j {
                    s += cs[i].p_a * w[i];
                    ws += w[i];
                }
            }
            if ws > 0.0 {
                *centre = s / ws;
            }
        }
    }
    let mut f = Vec3::zeros();
    let mut t = Vec3::zeros();
    for (j, centre) in centres.iter().enumerate() {
        let (mut nsum, mut dsum, mut ws) = (Vec3::zeros(), 0.0, 0.0);
        for i in 0..cs.len() {
            if assign[i] == j {
                nsum += cs[i].n * w[i];
                dsum += cs[i].depth_m * w[i];
                ws += w[i];
            }
        }
        if ws <= 0.0 || nsum.norm() == 0.0 {
            continue;
        }
        let n = nsum.normalize();
        let d = dsum / ws;
        if std::env::var("LOD_VERBOSE").is_ok() {
            println!(
                "  cluster {j}: at {:.2?} mm n {:.3?} d {:.3} mm weight {:.3}",
                (centre - tool_pos) * 1e3,
                n,
                d * 1e3,
                ws * 1e3
            );
        }
        let fk = -n * (k_c * (d + delta).max(0.0));
        f += fk;
        t += (centre - tool_pos).cross(&fk);
    }
    [f.x, f.y, f.z, t.x, t.y, t.z]
}

fn rel_err(a: &[Real; 6], b: &[Real; 6], lever: Real) -> Real {
    // Force in N, torque in N·m scaled by the tool radius so both count alike.
    let diff: Real = (0..6)
        .map(|i| {
            let s = if i < 3 { 1.0 } else { 1.0 / lever };
            ((a[i] - b[i]) * s).powi(2)
        })
        .sum::<Real>()
        .sqrt();
    let norm: Real = (0..6)
        .map(|i| {
            let s = if i < 3 { 1.0 } else { 1.0 / lever };
            (b[i] * s).powi(2)
        })
        .sum::<Real>()
        .sqrt();
    if norm > 0.0 { diff / norm } else { diff }
}

#[test]
#[ignore = "study on the shared jaws; run in release"]
fn lod_jaws() {
    let Some(upper) = read_stl(&format!("{MESHES}/jaw_upper_openfulljaw_p26.stl"), 1e-3) else {
        eprintln!("jaws not found; skipping");
        return;
    };
    let lower = read_stl(&format!("{MESHES}/jaw_lower_openfulljaw_p26.stl"), 1e-3).unwrap();
    // Tool body frame: the upper jaw's vertex centroid; the tool sits at its stored place.
    let c: Vec3 = upper.vertices().iter().sum::<Vec3>() / upper.vertices().len() as Real;
    let tool = TriMesh::new(
        upper.vertices().iter().map(|v| v - c).collect(),
        upper.triangles().to_vec(),
        DegeneratePolicy::Drop,
    )
    .unwrap()
    .0;
    let t0 = Instant::now();
    let mut lod = LodBackend::new(&tool, &[(lower, Pose::identity())]).unwrap();
    let build = t0.elapsed().as_secs_f64();
    let bs = lod.build_stats().clone();
    println!(
        "build: total {build:.3} s; tool {} tris {} nodes {:.3} s; obstacle {} tris {} nodes {:.3} s; memory {:.1} MB; radius {:.4} m",
        bs.tool.triangles,
        bs.tool.nodes,
        bs.tool.build_s,
        bs.obstacles[0].triangles,
        bs.obstacles[0].nodes,
        bs.obstacles[0].build_s,
        lod.memory_bytes() as Real / 1e6,
        lod.tool_bounding_radius_m()
    );
    // 200 poses: the stored placement moved by about 1 mm (smooth path) and tilted by < 1°.
    let delta: Real = std::env::var("LOD_DELTA")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(5e-4);
    let poses: Vec<Pose> = (0..200)
        .map(|i| {
            let s = i as Real / 200.0 * std::f64::consts::TAU;
            let dp = Vec3::new(
                0.5e-3 * s.sin(),
                0.5e-3 * (2.0 * s).cos(),
                0.3e-3 * (3.0 * s).sin() + 0.2e-3,
            );
            let rot = UnitQuaternion::from_scaled_axis(Vec3::new(
                0.005 * s.cos(),
                0.005 * s.sin(),
                0.003 * (2.0 * s).sin(),
            ));
            Pose {
                position: c + dp,
                orientation: rot,
            }
        })
        .collect();
    let mut out = ContactSet::new();
    let mut exact_wrench = Vec::new();
    // LOD_ONLY=0.025 times one threshold alone (for profiling).
    let only: Option<Real> = std::env::var("LOD_ONLY").ok().and_then(|s| s.parse().ok());
    for threshold in [0.0, 0.004, 0.01, 0.025, 0.05] {
        if only.is_some_and(|t| t != threshold) {
            continue;
        }
        let params = QueryParams::new(delta, threshold).unwrap();
        let mut times = Vec::new();
        let mut pairs = 0u64;
        let mut prims = 0u64;
        let mut ncontacts = 0usize;
        let mut errs = Vec::new();
        let mut fratio: Vec<Real> = Vec::new();
        let mut maxdepth_err: Real = 0.0;
        for (k, pose) in poses.iter().enumerate() {
            if std::env::var("LOD_VERBOSE").is_ok() && k > 0 {
                break;
            }
            let t = Instant::now();
            let st = lod.query(pose, &params, &mut out).unwrap();
            times.push(t.elapsed().as_secs_f64());
            pairs += st.node_pairs_tested;
            prims += st.primitive_pairs_tested;
            ncontacts += out.len();
            let wr = clustered_wrench(&out, delta, &pose.position);
            if threshold == 0.0 {
                exact_wrench.push((wr, out.max_depth_m().unwrap_or(-delta)));
            } else if k < exact_wrench.len() {
                errs.push(rel_err(&wr, &exact_wrench[k].0, 0.03));
                let f = |w: &[Real; 6]| Vec3::new(w[0], w[1], w[2]).norm();
                fratio.push(f(&wr) / f(&exact_wrench[k].0).max(1e-12));
                maxdepth_err = maxdepth_err
                    .max((out.max_depth_m().unwrap_or(-delta) - exact_wrench[k].1).abs());
            }
        }
        times.sort_by(|a, b| a.total_cmp(b));
        errs.sort_by(|a, b| a.total_cmp(b));
        fratio.sort_by(|a, b| a.total_cmp(b));
        let n = poses.len() as Real;
        println!(
            "threshold {threshold:.3}: median {:.1} us, p99 {:.1} us, node pairs {:.0}, primitive pairs {:.0}, contacts {:.1}, wrench err median {:.3} max {:.3}, max-depth err {:.2e} m",
            times[times.len() / 2] * 1e6,
            times[times.len() * 99 / 100] * 1e6,
            pairs as Real / n,
            prims as Real / n,
            ncontacts as Real / n,
            errs.get(errs.len() / 2).copied().unwrap_or(0.0),
            errs.last().copied().unwrap_or(0.0),
            maxdepth_err,
        );
        if !fratio.is_empty() {
            println!("  |F| / |F0|: median {:.3}", fratio[fratio.len() / 2]);
        }
    }
    // LOD_REPEAT=n: n more passes of queries alone (for profiling).
    let repeat: usize = std::env::var("LOD_REPEAT")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0);
    let params = QueryParams::new(delta, only.unwrap_or(0.025)).unwrap();
    for _ in 0..repeat {
        for pose in &poses {
            lod.query(pose, &params, &mut out).unwrap();
        }
    }
    // A far pose costs only the broad phase.
    let far = Pose::from_position(c + Vec3::new(1.0, 0.0, 0.0));
    let t = Instant::now();
    for _ in 0..1000 {
        lod.query(&far, &QueryParams::new(delta, 0.025).unwrap(), &mut out)
            .unwrap();
    }
    println!(
        "far tool: {:.0} ns per query",
        t.elapsed().as_secs_f64() * 1e6
    );
}
