//! One collision query, its clustering and its penalty wrench, printed as JSON: the reference
//! the Python package's tests compare against bit for bit (`python/tests`), and a quick way to
//! look at the contacts of a pose.
//!
//! ```text
//! cargo run --release -p haptic-collision --example query_contacts -- \
//!     --tool T.stl [--tool-scale S] --obstacle O.stl [--obstacle-scale S] \
//!     [--obstacle-pose x,y,z,qw,qx,qy,qz] [--pose x,y,z,qw,qx,qy,qz] [--delta D] \
//!     [--threshold T] [--backend lod|parry] [--clusters K] [--stiffness K] [--damping B] \
//!     [--mass KG] [--repeat N --time]
//! ```
//!
//! The meshes are loaded as `haptic.Mesh.load(path, scale)` loads them (the tool is not
//! recentred), the back-end is built as `haptic.LodBackend(tool, [(obstacle, pose)])`, the
//! representatives come from a fresh clusterer with warm start, and the wrench is the penalty
//! model's at rest for the tool's mass properties at the density that gives `--mass`. Numbers
//! are printed so that they read back to the same `f64`. With `--repeat N --time` it prints
//! only `{"median_s": …}`, the median wall time of N queries at the pose.

use std::collections::HashMap;
use std::time::Instant;

use haptic_cluster::{ClusterParams, Clusterer};
use haptic_collision::{LoadOptions, LodBackend, ParryBackend, TriMesh};
use haptic_core::{
    CollisionBackend, Contact, ContactModel, ContactSet, Kinematics, Pose, QueryParams, ToolState,
    Vec3,
};
use haptic_dynamics::{PenaltyModel, PenaltyParams};
use serde_json::{Value, json};

type Error = Box<dyn std::error::Error>;

fn numbers(text: &str, n: usize, what: &str) -> Result<Vec<f64>, Error> {
    let v: Vec<f64> = text
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{what}: {e}"))?;
    if v.len() != n {
        return Err(format!("{what}: {n} numbers, got {}", v.len()).into());
    }
    Ok(v)
}

fn pose(text: &str, what: &str) -> Result<Pose, Error> {
    let v = numbers(text, 7, what)?;
    Ok(Pose::new(
        Vec3::new(v[0], v[1], v[2]),
        nalgebra::Quaternion::new(v[3], v[4], v[5], v[6]),
    )?)
}

fn contacts_json(cs: &[Contact]) -> Value {
    let v3 =
        |f: fn(&Contact) -> Vec3| -> Vec<[f64; 3]> { cs.iter().map(|c| f(c).into()).collect() };
    json!({
        "p_a": v3(|c| c.p_a),
        "r_a": v3(|c| c.r_a),
        "p_b": v3(|c| c.p_b),
        "n": v3(|c| c.n),
        "depth": cs.iter().map(|c| c.depth_m).collect::<Vec<_>>(),
        "area": cs.iter().map(|c| c.area_m2).collect::<Vec<_>>(),
        "feature_a": cs.iter().map(|c| c.feature_a).collect::<Vec<_>>(),
        "feature_b": cs.iter().map(|c| c.feature_b).collect::<Vec<_>>(),
    })
}

fn query(
    backend: &mut dyn FnMut(&Pose, &QueryParams, &mut ContactSet) -> Result<(), Error>,
    args: &HashMap<String, String>,
    tool: &TriMesh,
) -> Result<Value, Error> {
    let get = |k: &str, d: &str| args.get(k).cloned().unwrap_or_else(|| d.to_owned());
    let at = pose(&get("pose", "0,0,0,1,0,0,0"), "--pose")?;
    let delta: f64 = get("delta", "0.001").parse()?;
    let params = QueryParams::new(delta, get("threshold", "0").parse()?)?;
    let mut raw = ContactSet::new();
    if args.contains_key("time") {
        let n: usize = get("repeat", "50").parse()?;
        let mut times = Vec::with_capacity(n);
        for _ in 0..n.max(1) {
            let start = Instant::now();
            backend(&at, &params, &mut raw)?;
            times.push(start.elapsed().as_secs_f64());
        }
        times.sort_by(f64::total_cmp);
        return Ok(json!({ "median_s": times[times.len() / 2], "contacts": raw.len() }));
    }
    backend(&at, &params, &mut raw)?;
    let mut clusterer = Clusterer::new(ClusterParams {
        max_clusters: get("clusters", "5").parse()?,
        ..ClusterParams::default()
    })?;
    let mut reps = ContactSet::new();
    clusterer.cluster(raw.as_slice(), delta, &mut reps)?;
    let mass: f64 = get("mass", "0.05").parse()?;
    let unit = tool.mass_properties(1.0)?;
    let body = tool.mass_properties(mass / unit.volume_m3)?.rigid_body()?;
    let mut model = PenaltyModel::new(PenaltyParams::new(
        get("stiffness", "2000").parse()?,
        get("damping", "2").parse()?,
        delta,
    )?)?;
    let y = ToolState::at_rest(&at).to_vector();
    let w = model.evaluate(
        &body,
        &y,
        &Kinematics::new(&body, &y),
        reps.as_slice(),
        None,
    )?;
    let mut out = contacts_json(raw.as_slice());
    out["representatives"] = contacts_json(reps.as_slice());
    out["representative_weights"] = json!(clusterer.representative_weights());
    out["force"] = json!(<[f64; 3]>::from(w.force));
    out["torque"] = json!(<[f64; 3]>::from(w.torque));
    Ok(out)
}

fn main() -> Result<(), Error> {
    let mut args = HashMap::new();
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let key = flag
            .strip_prefix("--")
            .ok_or_else(|| format!("unexpected argument {flag}"))?
            .to_owned();
        // `--flag=value` too, for values that start with a minus sign.
        if let Some((k, v)) = key.split_once('=') {
            args.insert(k.to_owned(), v.to_owned());
        } else if key == "time" {
            args.insert(key, String::new());
        } else {
            let value = it.next().ok_or_else(|| format!("{flag} needs a value"))?;
            args.insert(key, value);
        }
    }
    let get = |k: &str, d: &str| args.get(k).cloned().unwrap_or_else(|| d.to_owned());
    let load = |path: &str, scale: &str| -> Result<TriMesh, Error> {
        Ok(TriMesh::load(path, &LoadOptions::with_scale(scale.parse()?))?.0)
    };
    let tool = load(
        args.get("tool").ok_or("--tool is required")?,
        &get("tool-scale", "1"),
    )?;
    let obstacle = load(
        args.get("obstacle").ok_or("--obstacle is required")?,
        &get("obstacle-scale", "1"),
    )?;
    let obstacles = [(
        obstacle,
        pose(&get("obstacle-pose", "0,0,0,1,0,0,0"), "--obstacle-pose")?,
    )];
    let out = match get("backend", "lod").as_str() {
        "lod" => {
            let mut b = LodBackend::new(&tool, &obstacles)?;
            query(
                &mut |p, q, out| b.query(p, q, out).map(|_| ()).map_err(Into::into),
                &args,
                &tool,
            )?
        }
        "parry" => {
            let mut b = ParryBackend::new(&tool, &obstacles)?;
            query(
                &mut |p, q, out| b.query(p, q, out).map(|_| ()).map_err(Into::into),
                &args,
                &tool,
            )?
        }
        other => return Err(format!("unknown back-end {other}").into()),
    };
    println!("{out}");
    Ok(())
}
