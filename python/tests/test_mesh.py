"""haptic.Mesh and haptic.MassProperties: loading with a unit scale, arrays in and out, mass
properties, and the errors of every bad input."""

from __future__ import annotations

import numpy as np
import pytest

import haptic


def read_binary_stl(path) -> np.ndarray:
    """The corners of every triangle of a binary STL, `(m, 3, 3)` float64 in file units (the
    float32 values widened exactly)."""
    data = path.read_bytes()
    count = int(np.frombuffer(data, dtype="<u4", count=1, offset=80)[0])
    assert len(data) == 84 + 50 * count, f"{path} is not a binary STL"
    record = np.dtype([("normal", "<f4", (3,)), ("corners", "<f4", (3, 3)), ("attr", "<u2")])
    records = np.frombuffer(data, dtype=record, count=count, offset=84)
    return records["corners"].astype(np.float64)


def unique_rows(a: np.ndarray) -> np.ndarray:
    return np.unique(a.reshape(-1, 3), axis=0)


def test_load_stl_with_scale_matches_the_file(mesh_paths):
    path = mesh_paths["teaspoon"]
    scale = 1e-3
    mesh = haptic.Mesh.load(path, scale)
    corners = read_binary_stl(path) * scale

    v, t = mesh.vertices, mesh.triangles
    assert isinstance(v, np.ndarray) and isinstance(t, np.ndarray)
    assert v.dtype == np.float64 and v.ndim == 2 and v.shape[1] == 3
    assert t.dtype == np.uint32 and t.ndim == 2 and t.shape[1] == 3
    assert mesh.vertex_count == len(v) and mesh.triangle_count == len(t)
    assert len(t) + mesh.dropped_degenerate == len(corners)
    assert int(t.max()) < len(v)

    # Exactly equal corners are welded into one vertex: the vertex set is the corner set.
    assert np.array_equal(unique_rows(v), unique_rows(corners))

    # The triangles kept are the file's, in the file's order, corner for corner.
    kept = v[t]
    j = 0
    for i in range(len(kept)):
        while j < len(corners) and not np.array_equal(kept[i], corners[j]):
            j += 1
        assert j < len(corners), f"triangle {i} of the mesh is not in the file (in order)"
        j += 1


def test_scale_multiplies_the_vertices_exactly(mesh_paths):
    metres = haptic.Mesh.load(mesh_paths["teaspoon"])
    millimetres = haptic.Mesh.load(mesh_paths["teaspoon"], scale=1e-3)
    assert np.array_equal(metres.vertices * 1e-3, millimetres.vertices)
    assert np.array_equal(metres.triangles, millimetres.triangles)


def test_arrays_are_copies(mesh_paths):
    mesh = haptic.Mesh.load(mesh_paths["teaspoon"])
    v = mesh.vertices
    before = v.copy()
    v[:] = 0.0
    t = mesh.triangles
    t[:] = 0
    assert np.array_equal(mesh.vertices, before)
    assert mesh.triangles.max() > 0


def test_round_trip_through_arrays(mesh_paths):
    mesh = haptic.Mesh.load(mesh_paths["teacup"])
    again = haptic.Mesh(mesh.vertices, mesh.triangles)
    assert again.dropped_degenerate == 0
    assert np.array_equal(again.vertices, mesh.vertices)
    assert np.array_equal(again.triangles, mesh.triangles)
    # Any array-like: lists, int64 indices, a non-contiguous view.
    v = mesh.vertices
    wide = np.zeros((len(v), 6))
    wide[:, ::2] = v
    from_view = haptic.Mesh(wide[:, ::2], mesh.triangles.astype(np.int64))
    assert np.array_equal(from_view.vertices, v)
    box = haptic.Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                      [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    assert box.vertices.dtype == np.float64 and box.triangles.dtype == np.uint32
    assert box.triangle_count == 4


def test_degenerate_triangles_are_dropped_and_counted(make_box):
    v, t = make_box([0, 0, 0], [0.1, 0.1, 0.1])
    # Vertex 8 is the midpoint of the edge from vertex 0 to vertex 1.
    v = np.vstack([v, [[0.05, 0.0, 0.0]]])
    # A repeated vertex, and a zero-area triangle of three collinear vertices, among the faces.
    bad = np.vstack([t[:5], [[0, 0, 1]], t[5:], [[0, 8, 1]]])
    mesh = haptic.Mesh(v, bad)
    assert mesh.dropped_degenerate == 2
    assert np.array_equal(mesh.triangles, t)
    assert np.array_equal(mesh.vertices, v)


def test_mass_properties_of_a_cube(make_box):
    a = 0.1
    lo = np.array([0.3, -0.2, 0.1])
    v, t = make_box(lo, lo + a)
    mesh = haptic.Mesh(v, t)
    mp = mesh.mass_properties(density_kg_per_m3=1000.0)
    assert isinstance(mp, haptic.MassProperties)
    assert mp.volume_m3 == pytest.approx(1e-3, rel=1e-12)
    assert mp.mass_kg == pytest.approx(1.0, rel=1e-12)
    com = mp.centre_of_mass_m
    assert com.shape == (3,) and com.dtype == np.float64
    assert np.allclose(com, lo + a / 2, rtol=0, atol=1e-14)
    inertia = mp.inertia_about_com
    assert inertia.shape == (3, 3) and inertia.dtype == np.float64
    expected = np.eye(3) * (mp.mass_kg * a * a / 6.0)
    assert np.allclose(inertia, expected, rtol=1e-12, atol=1e-14)
    assert mp.boundary_edges == 0
    # Mass is linear in density.
    heavy = mesh.mass_properties(7800.0)
    assert heavy.mass_kg == pytest.approx(7.8, rel=1e-12)
    assert np.allclose(heavy.inertia_about_com, 7.8 * expected, rtol=1e-12, atol=1e-13)


def test_mass_properties_of_the_shared_meshes(mesh_paths):
    spoon = haptic.Mesh.load(mesh_paths["teaspoon"])
    mp = spoon.mass_properties(7800.0)
    assert mp.volume_m3 > 0
    lo, hi = spoon.bounding_box()
    assert np.all(mp.centre_of_mass_m > lo) and np.all(mp.centre_of_mass_m < hi)
    eig = np.linalg.eigvalsh(mp.inertia_about_com)
    assert np.all(eig > 0)
    # Principal moments of a physical body satisfy the triangle inequality.
    assert eig[0] + eig[1] >= eig[2] * (1 - 1e-9)


def test_translated_moves_every_vertex(mesh_paths):
    mesh = haptic.Mesh.load(mesh_paths["teaspoon"])
    offset = np.array([0.01, -0.25, 3.5])
    moved = mesh.translated(offset)
    assert np.array_equal(moved.vertices, mesh.vertices + offset)
    assert np.array_equal(moved.triangles, mesh.triangles)
    assert np.array_equal(mesh.vertices, haptic.Mesh.load(mesh_paths["teaspoon"]).vertices)
    moved_list = mesh.translated([0.0, 1.0, 0.0])
    assert np.array_equal(moved_list.vertices, mesh.vertices + [0.0, 1.0, 0.0])


def test_bounding_box(mesh_paths, make_box):
    mesh = haptic.Mesh.load(mesh_paths["teacup"], 2.0)
    lo, hi = mesh.bounding_box()
    used = mesh.vertices[np.unique(mesh.triangles)]
    assert lo.shape == (3,) and hi.shape == (3,)
    assert lo.dtype == np.float64 and hi.dtype == np.float64
    assert np.array_equal(lo, used.min(axis=0))
    assert np.array_equal(hi, used.max(axis=0))
    # A vertex no triangle uses is outside the box.
    v, t = make_box([0, 0, 0], [1, 2, 3])
    v = np.vstack([v, [[10.0, 10.0, 10.0]]])
    lo, hi = haptic.Mesh(v, t).bounding_box()
    assert np.array_equal(lo, [0, 0, 0]) and np.array_equal(hi, [1, 2, 3])


def test_obj_and_ply_files(tmp_path):
    # A unit cube of 0.1 m as quads (OBJ, 1-based indices) and as triangles (ASCII PLY).
    corners = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
    quads = [(0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]
    obj = tmp_path / "cube.obj"
    obj.write_text(
        "".join(f"v {x} {y} {z}\n" for x, y, z in corners)
        + "".join("f " + " ".join(str(i + 1) for i in q) + "\n" for q in quads)
    )
    tris = [(q[0], q[1], q[2]) for q in quads] + [(q[0], q[2], q[3]) for q in quads]
    ply = tmp_path / "cube.ply"
    ply.write_text(
        "ply\nformat ascii 1.0\n"
        f"element vertex {len(corners)}\nproperty float x\nproperty float y\nproperty float z\n"
        f"element face {len(tris)}\nproperty list uchar int vertex_indices\nend_header\n"
        + "".join(f"{x} {y} {z}\n" for x, y, z in corners)
        + "".join(f"3 {a} {b} {c}\n" for a, b, c in tris)
    )
    for path in (obj, ply):
        mesh = haptic.Mesh.load(path, scale=0.1)
        assert mesh.triangle_count == 12, path
        assert np.allclose(unique_rows(mesh.vertices), unique_rows(np.array(corners) * 0.1))
        assert mesh.mass_properties(1000.0).volume_m3 == pytest.approx(1e-3, rel=1e-6), path


# --- errors -----------------------------------------------------------------------------------


def test_exception_hierarchy():
    for cls in (haptic.InputError, haptic.MeshError, haptic.SceneError, haptic.CollisionError,
                haptic.ClusterError, haptic.DynamicsError, haptic.DeviceError,
                haptic.PipelineError):
        assert issubclass(cls, haptic.HapticError), cls
    assert issubclass(haptic.HapticError, Exception)
    assert issubclass(haptic.InputError, ValueError)
    assert not issubclass(haptic.MeshError, ValueError)


def test_wrong_shape_is_an_input_error(make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v[:, :2], t)
    assert e.value.field == "vertices"
    assert isinstance(e.value, ValueError) and isinstance(e.value, haptic.HapticError)
    assert isinstance(e.value.kind, str) and e.value.kind
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v.reshape(-1), t)
    assert e.value.field == "vertices"
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v, t[:, :2])
    assert e.value.field == "triangles"


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_vertex_is_an_input_error(make_box, bad):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    v[5, 1] = bad
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v, t)
    assert e.value.field == "vertices"


def test_index_out_of_range_is_a_mesh_error(make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    t = t.copy()
    t[3, 2] = 8  # there are 8 vertices
    with pytest.raises(haptic.MeshError) as e:
        haptic.Mesh(v, t)
    assert not isinstance(e.value, haptic.InputError)
    assert e.value.field == "triangles"


def test_negative_or_fractional_index_is_an_input_error(make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    neg = t.astype(np.int64)
    neg[0, 0] = -1
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v, neg)
    assert e.value.field == "triangles"
    frac = t.astype(np.float64)
    frac[0, 0] = 0.5
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v, frac)
    assert e.value.field == "triangles"


def test_empty_arrays_are_input_errors(make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(np.zeros((0, 3)), t)
    assert e.value.field == "vertices"
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v, np.zeros((0, 3), dtype=np.uint32))
    assert e.value.field == "triangles"
    with pytest.raises(haptic.InputError):
        haptic.Mesh([], [])


def test_wrong_dtype_is_an_input_error(make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(np.array([["a", "b", "c"]] * 8), t)
    assert e.value.field == "vertices"
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(np.array([[None, object(), 1.0]] * 8, dtype=object), t)
    assert e.value.field == "vertices"
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh(v, np.array([["x", "y", "z"]] * 12))
    assert e.value.field == "triangles"
    with pytest.raises(haptic.InputError):
        haptic.Mesh("not an array", t)


def test_missing_file_is_an_io_mesh_error(tmp_path):
    with pytest.raises(haptic.MeshError) as e:
        haptic.Mesh.load(tmp_path / "nowhere.stl")
    assert e.value.kind == "io"
    assert "nowhere.stl" in str(e.value)


def test_garbage_file_is_a_mesh_error(tmp_path):
    rng = np.random.default_rng(7)
    noise = rng.integers(0, 256, 5000, dtype=np.uint8)
    noise[:5] = np.frombuffer(b"\x00\x01\x02\x03\x04", dtype=np.uint8)  # not "solid"
    noise[80:84] = np.frombuffer(np.array([1000], "<u4").tobytes(), np.uint8)  # 1000 triangles
    for name, content in [
        ("short.stl", b"\x00\xffnot a mesh at all"),
        ("truncated.stl", noise.tobytes()),
        ("noise.obj", b"v 1 2\nf 1 2 x\n\x00\xff\xfe"),
        ("noise.ply", b"ply\nformat nonsense\n" + bytes(range(256))),
    ]:
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(haptic.MeshError) as e:
            haptic.Mesh.load(path)
        assert e.value.kind != "io", name


def test_unsupported_extension_is_a_mesh_error(tmp_path):
    path = tmp_path / "cube.xyz"
    path.write_text("0 0 0\n")
    with pytest.raises(haptic.MeshError):
        haptic.Mesh.load(path)


@pytest.mark.parametrize("scale", [0.0, -1.0, float("nan"), float("inf")])
def test_bad_scale_is_an_input_error(mesh_paths, scale):
    with pytest.raises(haptic.InputError) as e:
        haptic.Mesh.load(mesh_paths["teaspoon"], scale)
    assert e.value.field == "scale"


@pytest.mark.parametrize("density", [0.0, -1.0, float("nan")])
def test_bad_density_is_an_input_error(make_box, density):
    mesh = haptic.Mesh(*make_box([0, 0, 0], [1, 1, 1]))
    with pytest.raises(haptic.InputError) as e:
        mesh.mass_properties(density)
    assert e.value.field == "density_kg_per_m3"


def test_inside_out_mesh_has_no_mass_properties(make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    inside_out = haptic.Mesh(v, t[:, ::-1])
    with pytest.raises(haptic.MeshError):
        inside_out.mass_properties(1000.0)


def test_non_finite_offset_is_an_input_error(mesh_paths):
    mesh = haptic.Mesh.load(mesh_paths["teaspoon"])
    with pytest.raises(haptic.InputError) as e:
        mesh.translated([0.0, np.nan, 0.0])
    assert e.value.field == "offset"
    with pytest.raises(haptic.InputError) as e:
        mesh.translated([0.0, 1.0])
    assert e.value.field == "offset"


def test_a_triangle_wound_against_its_neighbours_is_found_turned_back_and_refused(make_box):
    v, t = make_box([0, 0, 0], [0.1, 0.1, 0.1])
    good = haptic.Mesh(v, t)
    assert good.winding_conflicts == 0 and good.rewound_triangles == 0
    bad_t = t.copy()
    bad_t[4] = bad_t[4][[0, 2, 1]]
    bad = haptic.Mesh(v, bad_t)
    # Kept as given, and counted: its three edges run the same way as its neighbours'.
    assert np.array_equal(bad.triangles, bad_t)
    assert bad.winding_conflicts == 3
    # The back-ends refuse it: its contacts would push the wrong way.
    tool = haptic.Mesh(*make_box([-0.01, -0.01, -0.01], [0.01, 0.01, 0.01]))
    with pytest.raises(haptic.CollisionError, match="wound against each other"):
        haptic.LodBackend(tool, [(bad, np.array([0, 0, 0, 1, 0, 0, 0.0]))])
    repaired = bad.with_consistent_winding()
    assert repaired.rewound_triangles == 1 and repaired.winding_conflicts == 0
    assert np.array_equal(repaired.triangles, t)
    haptic.LodBackend(tool, [(repaired, np.array([0, 0, 0, 1, 0, 0, 0.0]))])


def test_loading_turns_triangles_wound_against_their_neighbours(tmp_path, make_box):
    v, t = make_box([0, 0, 0], [1, 1, 1])
    t = t.copy()
    t[7] = t[7][[0, 2, 1]]
    lines = [f"v {x} {y} {z}" for x, y, z in v] + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in t]
    path = tmp_path / "box_one_turned.obj"
    path.write_text("\n".join(lines) + "\n")
    mesh = haptic.Mesh.load(path)
    assert mesh.rewound_triangles == 1 and mesh.winding_conflicts == 0
    assert mesh.dropped_duplicates == 0
    assert mesh.mass_properties(1000.0).volume_m3 == pytest.approx(1.0, rel=1e-12)
    # A triangle listed twice (rotated) is dropped once: it would push twice.
    path.write_text("\n".join(lines + [f"f {t[2][1] + 1} {t[2][2] + 1} {t[2][0] + 1}"]) + "\n")
    again = haptic.Mesh.load(path)
    assert again.dropped_duplicates == 1 and again.triangle_count == 12
