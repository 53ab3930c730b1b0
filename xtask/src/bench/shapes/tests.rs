//! The procedural meshes: closed, consistently oriented, and as dense as asked.

use std::collections::HashMap;

use super::*;

/// Millimetre (m).
const MM: Real = 1e-3;

/// Asserts that every directed edge appears once and its reverse once: closed and
/// consistently oriented. Also checks the mesh's own boundary count.
fn assert_closed(mesh: &TriMesh) {
    assert_eq!(mesh.boundary_edge_count(), 0);
    let mut directed = HashMap::<(u32, u32), usize>::new();
    for t in mesh.triangles() {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *directed.entry((a, b)).or_default() += 1;
        }
    }
    for (&(a, b), &count) in &directed {
        assert_eq!(count, 1, "edge {a}→{b} used {count} times in one direction");
        assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}→{b} has no twin");
    }
}

/// Volume (m³) from the mass properties at unit density.
fn volume(mesh: &TriMesh) -> anyhow::Result<Real> {
    Ok(mesh.mass_properties(1.0)?.volume_m3)
}

/// Asserts that density 2 has 3.5 to 4.5 times the triangles of density 1.
fn assert_ratio(coarse: &TriMesh, fine: &TriMesh) {
    let ratio = fine.triangles().len() as Real / coarse.triangles().len() as Real;
    assert!((3.5..=4.5).contains(&ratio), "triangle ratio {ratio}");
}

/// Area of the regular `segments`-gon inscribed in the unit circle, over π.
fn polygon_factor(segments: usize) -> Real {
    let step = TAU / segments as Real;
    step.sin() / step
}

/// Mean of `(r + offset)²` (m²) over a pitch of the thread's phase, by the midpoint rule.
fn mean_square_radius(thread: &ThreadProfile, offset: Real) -> Real {
    let n = 20_000;
    (0..n)
        .map(|k| {
            let z = thread.pitch * (k as Real + 0.5) / n as Real;
            (thread.radius(0.0, z) + offset).powi(2)
        })
        .sum::<Real>()
        / n as Real
}

#[test]
fn box_is_closed_with_exact_volume() -> anyhow::Result<()> {
    let half = Vec3::new(10.0 * MM, 20.0 * MM, 30.0 * MM);
    let coarse = box_mesh(half, 1)?;
    let fine = box_mesh(half, 2)?;
    let exact = 8.0 * half.x * half.y * half.z;
    for mesh in [&coarse, &fine] {
        assert_closed(mesh);
        let v = volume(mesh)?;
        assert!(((v - exact) / exact).abs() < 1e-12, "volume {v} vs {exact}");
    }
    assert_eq!(coarse.triangles().len(), 192);
    assert_eq!(fine.triangles().len(), 768);
    assert_eq!(coarse.vertices().len(), 98);
    assert_ratio(&coarse, &fine);
    Ok(())
}

#[test]
fn gears_are_closed_with_plausible_volume() -> anyhow::Result<()> {
    let (module, width) = (1.0 * MM, 10.0 * MM);
    for (teeth, counts) in [(20, [4_800, 17_280]), (35, [8_400, 30_240])] {
        let profile = GearProfile::new(teeth, module)?;
        // Volume of the exact outline: w·z·½∫r(φ)² dφ over one tooth pitch (midpoint rule).
        let (n, pitch_angle) = (20_000, TAU / teeth as Real);
        let exact = width
            * teeth as Real
            * (0..n)
                .map(|k| {
                    0.5 * profile
                        .radius(pitch_angle * (k as Real + 0.5) / n as Real)
                        .powi(2)
                })
                .sum::<Real>()
            * pitch_angle
            / n as Real;
        let disc = |r: Real| PI * r * r * width;
        let pitch_disc = disc(module * teeth as Real / 2.0);
        let mut meshes = Vec::new();
        for (density, count) in [1, 2].into_iter().zip(counts) {
            let mesh = spur_gear(teeth, module, width, density)?;
            assert_closed(&mesh);
            assert_eq!(mesh.triangles().len(), count);
            let v = volume(&mesh)?;
            assert!(
                (disc(profile.root_radius)..=disc(profile.tip_radius)).contains(&v),
                "{teeth} teeth: volume {v} outside the root and tip discs"
            );
            // Standard involute teeth with a 1.25·m dedendum take slightly more from the pitch
            // disc than they add: 2.04 % at 20 teeth, 1.0 % at 35 (exact outlines; the meshes
            // are within 0.05 % of those).
            assert!(
                ((v - pitch_disc) / pitch_disc).abs() < 0.025,
                "{teeth} teeth: volume {v} vs pitch disc {pitch_disc}"
            );
            assert!(
                ((v - exact) / exact).abs() < 2e-3,
                "{teeth} teeth: volume {v} vs exact outline {exact}"
            );
            meshes.push(mesh);
        }
        assert_ratio(&meshes[0], &meshes[1]);
    }
    Ok(())
}

/// Smallest `ρ − r_a(φ)` (m) over the vertices of b posed by `(centre, angle)` in a's frame
/// (polar `ρ, φ`), and likewise over a's vertices in b's frame against `r_b`: negative when a
/// vertex of one gear lies inside the other's exact outline.
fn pair_margin(
    (a, profile_a): (&TriMesh, &GearProfile),
    (b, profile_b): (&TriMesh, &GearProfile),
    centre: Vec3,
    angle: Real,
) -> Real {
    let (c, s) = (angle.cos(), angle.sin());
    let outside_a = b.vertices().iter().map(|v| {
        let (x, y) = (centre.x + c * v.x - s * v.y, centre.y + s * v.x + c * v.y);
        x.hypot(y) - profile_a.radius(y.atan2(x))
    });
    let outside_b = a.vertices().iter().map(|v| {
        let (dx, dy) = (v.x - centre.x, v.y - centre.y);
        let (x, y) = (c * dx + s * dy, -s * dx + c * dy);
        x.hypot(y) - profile_b.radius(y.atan2(x))
    });
    outside_a.chain(outside_b).fold(Real::INFINITY, Real::min)
}

#[test]
fn gear_pair_meshes_without_intersecting() -> anyhow::Result<()> {
    let (module, width, clearance) = (1.0 * MM, 10.0 * MM, 0.19 * MM);
    // 35 teeth (odd) and 20 teeth (even) as gear b exercise both rotations.
    for (teeth_a, teeth_b) in [(20, 35), (35, 20)] {
        let profile_a = GearProfile::new(teeth_a, module)?;
        let profile_b = GearProfile::new(teeth_b, module)?;
        for density in [1, 2] {
            let (a, b, centre, angle) =
                gear_pair(teeth_a, teeth_b, module, width, clearance, density)?;
            let expected = module * (teeth_a + teeth_b) as Real / 2.0 + clearance;
            assert!((centre - Vec3::new(expected, 0.0, 0.0)).norm() < 1e-15);
            let margin = pair_margin((&a, &profile_a), (&b, &profile_b), centre, angle);
            // The flanks' backlash is about clearance·sin 20° normal to them, more radially.
            assert!(
                margin > 0.25 * clearance,
                "{teeth_a}/{teeth_b} at density {density}: margin {margin}"
            );
            // Half a tooth pitch off, tooth meets tooth: the check must see it.
            let wrong = angle + PI / teeth_b as Real;
            let margin = pair_margin((&a, &profile_a), (&b, &profile_b), centre, wrong);
            assert!(
                margin < -0.25 * module,
                "wrong rotation not detected: {margin}"
            );
        }
    }
    Ok(())
}

#[test]
fn rod_is_closed_with_plausible_volume() -> anyhow::Result<()> {
    let (major, minor, pitch, length) = (4.0 * MM, 3.2 * MM, 1.25 * MM, 20.0 * MM);
    let thread = ThreadProfile::new(major, minor, pitch)?;
    let cylinder = |r: Real| PI * r * r * length;
    let mut meshes = Vec::new();
    for (density, count) in [(1, 9_318), (2, 37_068)] {
        let mesh = threaded_rod(major, minor, pitch, length, density)?;
        assert_closed(&mesh);
        assert_eq!(mesh.triangles().len(), count);
        let v = volume(&mesh)?;
        assert!(
            (cylinder(minor)..=cylinder(major)).contains(&v),
            "volume {v}"
        );
        // Each cross-section of the exact rod has area π·mean(r²); the mesh's is the polygon.
        let expected =
            PI * length * mean_square_radius(&thread, 0.0) * polygon_factor(32 * density);
        assert!(
            ((v - expected) / expected).abs() < 2e-3,
            "volume {v} vs {expected}"
        );
        let (lo, hi) = mesh.bounding_box();
        assert!(lo.z.abs() < 1e-15 && (hi.z - length).abs() < 1e-15);
        meshes.push(mesh);
    }
    assert_ratio(&meshes[0], &meshes[1]);
    Ok(())
}

#[test]
fn nut_is_closed_with_plausible_volume() -> anyhow::Result<()> {
    let (major, minor, pitch) = (4.0 * MM, 3.2 * MM, 1.25 * MM);
    let (length, outer, clearance) = (8.0 * MM, 7.0 * MM, 0.1 * MM);
    let thread = ThreadProfile::new(major, minor, pitch)?;
    let annulus = |inner: Real| PI * (outer * outer - inner * inner) * length;
    let mut meshes = Vec::new();
    for (density, count) in [(1, 3_974), (2, 15_584)] {
        let mesh = threaded_nut(major, minor, pitch, length, outer, clearance, density)?;
        assert_closed(&mesh);
        assert_eq!(mesh.triangles().len(), count);
        let v = volume(&mesh)?;
        assert!(
            (annulus(major + clearance)..=annulus(minor + clearance)).contains(&v),
            "volume {v}"
        );
        let expected = PI
            * length
            * (outer * outer - mean_square_radius(&thread, clearance))
            * polygon_factor(32 * density);
        assert!(
            ((v - expected) / expected).abs() < 2e-3,
            "volume {v} vs {expected}"
        );
        meshes.push(mesh);
    }
    assert_ratio(&meshes[0], &meshes[1]);
    Ok(())
}

/// The rod's and the nut's vertices lie on their profiles, the nut's `clearance` outside
/// the rod's (the faces between vertices cut the profile's corners: the meshes' own gap is
/// smaller, and the suite's scene says so).
#[test]
fn rod_and_nut_vertices_lie_on_their_profiles() -> anyhow::Result<()> {
    let (major, minor, pitch) = (4.0 * MM, 3.2 * MM, 1.25 * MM);
    let (length, outer, clearance) = (8.0 * MM, 7.0 * MM, 0.1 * MM);
    let thread = ThreadProfile::new(major, minor, pitch)?;
    let nut_radius = |theta: Real, z: Real| thread.radius(theta, z) + clearance;
    for density in [1, 2] {
        let rod = threaded_rod(major, minor, pitch, 20.0 * MM, density)?;
        let nut = threaded_nut(major, minor, pitch, length, outer, clearance, density)?;
        // The nut's inner vertices lie on its profile function.
        let mut inner = 0;
        for v in nut
            .vertices()
            .iter()
            .filter(|v| v.xy().norm() < outer - 1e-6)
        {
            let gap = v.xy().norm() - nut_radius(v.y.atan2(v.x), v.z);
            assert!(
                gap.abs() < 1e-12,
                "nut vertex {v:?} off its profile by {gap}"
            );
            inner += 1;
        }
        assert!(inner > 0);
        // Every rod vertex along the nut is a clearance inside the nut's surface.
        let mut along = 0;
        for v in rod.vertices().iter().filter(|v| v.z <= length) {
            let gap = nut_radius(v.y.atan2(v.x), v.z) - v.xy().norm();
            assert!(gap >= clearance - 1e-12, "rod vertex {v:?}: gap {gap}");
            along += 1;
        }
        assert!(along > 0);
    }
    Ok(())
}

#[test]
fn peg_and_bushing_are_closed_with_plausible_volume() -> anyhow::Result<()> {
    let (r, bore, outer, length) = (4.0 * MM, 4.05 * MM, 7.0 * MM, 10.0 * MM);
    let pegs = [round_peg(r, length, 1)?, round_peg(r, length, 2)?];
    let bushings = [
        bushing(bore, outer, length, 1)?,
        bushing(bore, outer, length, 2)?,
    ];
    for (density, (peg, bushing)) in [1, 2].into_iter().zip(pegs.iter().zip(&bushings)) {
        assert_closed(peg);
        assert_closed(bushing);
        let peg_exact = std::f64::consts::PI * r * r * length * polygon_factor(40 * density);
        let ring = polygon_factor(33 * density) * (outer * outer - bore * bore);
        let bushing_exact = std::f64::consts::PI * ring * length;
        for (v, exact) in [(volume(peg)?, peg_exact), (volume(bushing)?, bushing_exact)] {
            assert!(((v - exact) / exact).abs() < 1e-9, "volume {v} vs {exact}");
        }
        assert_eq!(peg.triangles().len(), 80 * density * (4 * density + 1));
        assert_eq!(bushing.triangles().len(), 132 * density * (5 * density + 1));
    }
    assert_ratio(&pegs[0], &pegs[1]);
    assert_ratio(&bushings[0], &bushings[1]);
    Ok(())
}

#[test]
fn bad_parameters_are_errors() {
    assert!(box_mesh(Vec3::new(1.0, 1.0, 1.0), 0).is_err());
    assert!(box_mesh(Vec3::new(1.0, -1.0, 1.0), 1).is_err());
    assert!(spur_gear(2, MM, MM, 1).is_err());
    assert!(spur_gear(20, Real::NAN, MM, 1).is_err());
    assert!(gear_pair(20, 35, MM, MM, -MM, 1).is_err());
    assert!(threaded_rod(3.0 * MM, 4.0 * MM, MM, 10.0 * MM, 1).is_err());
    assert!(threaded_nut(4.0 * MM, 3.2 * MM, MM, 8.0 * MM, 4.05 * MM, 0.1 * MM, 1).is_err());
    assert!(round_peg(-MM, MM, 1).is_err());
    assert!(bushing(5.0 * MM, 4.0 * MM, MM, 1).is_err());
    assert!(bushing(4.0 * MM, 5.0 * MM, MM, 0).is_err());
}

/// The largest radial distance (m) from the thread surface `r(θ, z) + offset` of the points of
/// `mesh`'s facets that lie on it (every vertex strictly between `z_lo` and `z_hi` and off the
/// axis and the outer cylinder, so the end facets and caps are left out), sampled on a
/// barycentric grid of each facet.
fn facet_deviation(
    mesh: &TriMesh,
    thread: &ThreadProfile,
    offset: Real,
    (z_lo, z_hi): (Real, Real),
    max_radius: Real,
) -> Real {
    let v = mesh.vertices();
    let mut worst: Real = 0.0;
    let n = 8;
    for t in mesh.triangles() {
        let p = t.map(|i| v[i as usize]);
        if p.iter()
            .any(|q| q.z <= z_lo || q.z >= z_hi || q.xy().norm() > max_radius)
        {
            continue;
        }
        for i in 0..=n {
            for j in 0..=n - i {
                let (a, b) = (i as Real / n as Real, j as Real / n as Real);
                let q = p[0] * (1.0 - a - b) + p[1] * a + p[2] * b;
                let dev = q.xy().norm() - (thread.radius(q.y.atan2(q.x), q.z) + offset);
                worst = worst.max(dev.abs());
            }
        }
    }
    worst
}

/// The rod's and the nut's facets follow the thread's profile, corners included: every point
/// of a facet away from the ends lies within the chord's sagitta of the surface (plus the
/// helix's twist across a facet), at both densities. A grid of constant-z rows cut the corners by
/// up to 0.15 mm, more than the suite's 0.1 mm clearance.
#[test]
fn thread_facets_follow_the_profile() -> anyhow::Result<()> {
    let (major, minor, pitch) = (4.0 * MM, 3.2 * MM, 1.25 * MM);
    let (length, outer, clearance) = (8.0 * MM, 7.0 * MM, 0.1 * MM);
    let thread = ThreadProfile::new(major, minor, pitch)?;
    for density in [1, 2] {
        let rod = threaded_rod(major, minor, pitch, 20.0 * MM, density)?;
        let nut = threaded_nut(major, minor, pitch, length, outer, clearance, density)?;
        let band = 0.2 * pitch;
        let rod_dev = facet_deviation(&rod, &thread, 0.0, (band, 20.0 * MM - band), major);
        let nut_dev = facet_deviation(
            &nut,
            &thread,
            clearance,
            (band, length - band),
            outer - 1e-6,
        );
        let sagitta = (major + clearance) * (1.0 - (PI / (32 * density) as Real).cos());
        println!("density {density}: rod {rod_dev:e}, nut {nut_dev:e}, sagitta {sagitta:e}");
        assert!(
            rod_dev <= 1.5 * sagitta,
            "rod facets {rod_dev} off the profile"
        );
        assert!(
            nut_dev <= 1.5 * sagitta,
            "nut facets {nut_dev} off the profile"
        );
    }
    Ok(())
}

/// Total area of the triangles (m²).
fn area(mesh: &TriMesh) -> Real {
    let v = mesh.vertices();
    mesh.triangles()
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| v[i as usize]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .sum()
}

/// A remeshed copy is the same closed surface: the same area and volume, four (at the edges'
/// midpoints) or three (at the centroids) times the triangles, closed and oriented as before.
#[test]
fn remeshed_copies_keep_the_surface() -> anyhow::Result<()> {
    for mesh in [
        box_mesh(Vec3::new(3.0 * MM, 2.0 * MM, 1.0 * MM), 1)?,
        round_peg(4.0 * MM, 6.0 * MM, 1)?,
    ] {
        let (a0, v0) = (area(&mesh), volume(&mesh)?);
        for (copy, factor) in [
            (split_at_midpoints(&mesh)?, 4),
            (split_at_centroids(&mesh)?, 3),
        ] {
            assert_closed(&copy);
            assert_eq!(copy.triangles().len(), factor * mesh.triangles().len());
            assert!(
                (area(&copy) / a0 - 1.0).abs() < 1e-12,
                "{} {a0}",
                area(&copy)
            );
            assert!((volume(&copy)? / v0 - 1.0).abs() < 1e-12);
        }
        // Midpoints shared along every edge: `V + E` vertices, `E = 3F/2`.
        let midpoints = split_at_midpoints(&mesh)?;
        let edges = 3 * mesh.triangles().len() / 2;
        assert_eq!(midpoints.vertices().len(), mesh.vertices().len() + edges);
    }
    Ok(())
}

#[test]
fn surfaces_of_revolution_are_closed_with_plausible_volume() -> anyhow::Result<()> {
    let (r, inner, outer) = (10.0 * MM, 10.2 * MM, 13.0 * MM);
    let (ring_r, tube, cone_r, height) = (12.0 * MM, 3.0 * MM, 20.0 * MM, 40.0 * MM);
    let mut meshes = Vec::new();
    for density in [1, 2] {
        let shapes = [
            ball(r, density)?,
            socket(inner, outer, density)?,
            ring(ring_r, tube, density)?,
            cone(cone_r, height, density)?,
        ];
        let exact = [
            4.0 / 3.0 * PI * r.powi(3),
            2.0 / 3.0 * PI * (outer.powi(3) - inner.powi(3)),
            2.0 * PI * PI * ring_r * tube * tube,
            PI * cone_r * cone_r * height / 3.0,
        ];
        let triangles = [
            96 * density * (24 * density - 1),
            2304 * density * density,
            2048 * density * density,
            48 * density * (16 * density - 2),
        ];
        // Inscribed: a little less than the smooth solid, by no more than twice what the regular
        // polygons about the axis and along the profile (a full circle of it) lose in area.
        let around = polygon_factor(48 * density);
        let lower = [
            around * polygon_factor(48 * density),
            around * polygon_factor(48 * density),
            polygon_factor(64 * density) * polygon_factor(16 * density),
            around,
        ];
        for (((mesh, exact), count), lower) in shapes.iter().zip(exact).zip(triangles).zip(lower) {
            assert_closed(mesh);
            assert_eq!(mesh.triangles().len(), count);
            let v = volume(mesh)?;
            assert!(
                v < exact && v > exact * lower * lower,
                "volume {v} vs {exact}"
            );
        }
        meshes.push(shapes);
    }
    for (coarse, fine) in meshes[0].iter().zip(&meshes[1]) {
        assert_ratio(coarse, fine);
    }
    assert!(socket(inner, inner, 1).is_err());
    assert!(ring(tube, tube, 1).is_err());
    assert!(cone(cone_r, height, 0).is_err());
    assert!(ball(-r, 1).is_err());
    Ok(())
}
