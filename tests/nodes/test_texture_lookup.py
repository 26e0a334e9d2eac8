"""texture_lookup in real graphs built from YAML files.

Expected values come from the ground-truth synthetic models (coefficients
from chosen poles), the float64 numpy reference LSF -> polynomial conversion,
and scipy.spatial.Delaunay barycentric coordinates.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial import Delaunay

from flowtex.datasets.model_sets import cork_like_model_set, hard_model_set, lsf_to_poly_reference
from flowtex.dsp.lsf import lsf_to_poly_new
from flowtex.errors import GraphError
from flowtex.graph.compiled import load_graph
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import save_model_set


def graph_file(folder: Path, models: str, rate: float = 1000, extra: str = "", outside: str | None = "fade") -> Path:
    """A graph speed, force -> texture_lookup -> its four outputs; ``outside: fade`` (HaTT's rule, the reference's) unless given;
    ``outside=None``: no ``outside`` parameter (the node's default)."""
    rule = "" if outside is None else f", outside: {outside}"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "lookup.yaml"
    path.write_text(textwrap.dedent(f"""\
        flowtex: 1
        name: lookup
        rate: {rate}
        inputs:
          speed: {{unit: mm/s}}
          force: {{unit: N}}
        nodes:
          lookup:
            type: texture_lookup
            params: {{models: {models!r}{rule}{extra}}}
        edges:
          - speed -> lookup.speed
          - force -> lookup.force
        outputs:
          ar: lookup.ar
          ma: lookup.ma
          gain: lookup.gain
          variance: lookup.variance
        """))
    return path


@pytest.fixture(scope="module")
def cork(tmp_path_factory):
    ms = cork_like_model_set()
    root = tmp_path_factory.mktemp("cork")
    (root / "my models").mkdir()
    write_hatt_xml(ms, root / "my models" / "Models_Cork Like.xml")
    graph = load_graph(graph_file(root / "graphs", "../my models/Models_Cork Like.xml"))
    return ms, graph


@pytest.fixture(scope="module")
def hard(tmp_path_factory):
    ms = hard_model_set()
    root = tmp_path_factory.mktemp("hard")
    path = write_hatt_xml(ms, root / "Models_Hard Cases.xml")
    graph = load_graph(graph_file(root / "g", str(path.resolve())))  # absolute path
    return ms, graph


def in_range(ms):
    """Models whose (speed, force) is not changed by HaTT's clamping."""
    return [m for m in range(ms.num_models)
            if 0.05 <= ms.speeds[m] <= ms.max_speed and 0.05 <= ms.forces[m] <= ms.max_force
            and ms.speeds[m] != ms.max_speed and ms.forces[m] != ms.max_force]


def reference_model(ms, q):
    """Independent expectation at an in-hull point: scipy barycentric weights, numpy LSF -> polynomial."""
    d = Delaunay(ms.points())
    s = int(d.find_simplex(q))
    assert s >= 0
    T = d.transform[s]
    b = T[:2] @ (np.asarray(q) - T[2])
    w = np.array([b[0], b[1], 1 - b.sum()])
    v = d.simplices[s]
    ar = lsf_to_poly_reference(w @ ms.ar_lsf[v])
    ma = lsf_to_poly_reference(w @ ms.ma_lsf[v])
    return ar, ma, float(w @ ms.gain[v]), float(w @ ms.variance[v])


def test_output_shapes_follow_the_file(cork, hard):
    assert cork[1].outputs["ar"].shape == (20,) and cork[1].outputs["ma"].shape == (18,)
    assert hard[1].outputs["ar"].shape == (13,) and hard[1].outputs["ma"].shape == (11,)
    assert cork[1].outputs["gain"].shape == () and cork[1].outputs["variance"].unit == ""


def test_exact_vertex_gives_that_models_coefficients(cork):
    ms, g = cork
    g.reset()
    models = in_range(ms)
    assert len(models) == 17  # the scattered interior models; edge and corner ones are clamped
    for m in models:
        out = g.step({"speed": ms.speeds[m], "force": ms.forces[m]})
        assert np.array_equal(out["ar"], lsf_to_poly_new(ms.ar_lsf[m])), m
        assert np.array_equal(out["ma"], lsf_to_poly_new(ms.ma_lsf[m])), m
        # the file's coefficients (written with repr: full precision) -- from the models' poles
        assert np.allclose(out["ar"], ms.ar_coeff[m], rtol=0, atol=1e-10)
        assert np.allclose(out["ma"], ms.ma_coeff[m], rtol=0, atol=1e-10)
        assert out["gain"] == ms.gain[m] and out["variance"] == ms.variance[m]


def test_interior_points_match_independent_reference(cork):
    ms, g = cork
    rng = np.random.default_rng(2)
    q = np.column_stack([rng.uniform(1, ms.max_speed - 1, 60), rng.uniform(0.1, ms.max_force - 0.05, 60)])
    q = q[Delaunay(ms.points()).find_simplex(q) >= 0]
    out = g.run({"speed": q[:, 0], "force": q[:, 1]})
    for i, point in enumerate(q):
        ar, ma, gain, var = reference_model(ms, point)
        assert np.allclose(out["ar"][i], ar, rtol=0, atol=1e-11)
        assert np.allclose(out["ma"][i], ma, rtol=0, atol=1e-11)
        assert out["gain"][i] == pytest.approx(gain, rel=1e-13)
        assert out["variance"][i] == pytest.approx(var, rel=1e-12, abs=1e-18)
        assert np.abs(np.roots(out["ar"][i])).max() < 1.0


def test_step_change_takes_effect_on_the_same_tick(cork):
    ms, g = cork
    a, b = in_range(ms)[:2]
    speed = np.array([ms.speeds[a]] * 5 + [ms.speeds[b]] * 3)
    force = np.array([ms.forces[a]] * 5 + [ms.forces[b]] * 3)
    out = g.run({"speed": speed, "force": force})
    assert np.array_equal(out["ar"][4], lsf_to_poly_new(ms.ar_lsf[a]))
    assert np.array_equal(out["ar"][5], lsf_to_poly_new(ms.ar_lsf[b]))
    assert out["variance"][5] == ms.variance[b] and out["gain"][5] == ms.gain[b]


def test_nan_holds_last_model_and_silence_before_any(cork):
    ms, g = cork
    a, b = in_range(ms)[2:4]
    nan = math.nan
    speed = np.array([nan, ms.speeds[a], nan, ms.speeds[a], nan, ms.speeds[b]])
    force = np.array([1.0, ms.forces[a], ms.forces[a], nan, nan, ms.forces[b]])
    out = g.run({"speed": speed, "force": force}, nonfinite="pass")
    assert out["ar"][0].tolist() == [1.0] + [0.0] * 19 and out["ma"][0].tolist() == [1.0] + [0.0] * 17
    assert out["gain"][0] == 0.0 and out["variance"][0] == 0.0
    for row in (2, 3, 4):
        assert np.array_equal(out["ar"][row], out["ar"][1]) and out["variance"][row] == ms.variance[a]
    assert np.array_equal(out["ar"][5], lsf_to_poly_new(ms.ar_lsf[b]))
    assert all(np.all(np.isfinite(v)) for v in out.values())


def test_infinite_and_huge_inputs_clamp_like_the_maximum(cork):
    ms, g = cork
    top = (ms.max_speed - 0.01, ms.max_force - 0.01)
    speed = np.array([math.inf, 1e300, top[0], -math.inf, -1.0, 0.0, 0.0001])
    force = np.array([math.inf, 1e300, top[1], -math.inf, -1.0, 0.0, 0.0001])
    out = g.run({"speed": speed, "force": force}, nonfinite="pass")
    for row in (0, 1):
        assert np.array_equal(out["ar"][row], out["ar"][2]) and out["variance"][row] == out["variance"][2]
    for row in (3, 4, 5):
        assert np.array_equal(out["ar"][row], out["ar"][6]) and out["variance"][row] == out["variance"][6]
    assert out["variance"][6] < 1e-6 * ms.variance.max()  # next to the silent corner


def test_block_split_and_stepping_give_identical_numbers(cork):
    ms, g = cork
    rng = np.random.default_rng(4)
    n = 3000
    speed = np.clip(np.cumsum(rng.normal(0, 8, n)) + 150, -20, 450)
    force = np.clip(np.cumsum(rng.normal(0, 0.05, n)) + 2, -0.5, 5)
    speed[rng.integers(0, n, 30)] = math.nan
    whole = g.run({"speed": speed, "force": force}, nonfinite="pass")
    g.reset()
    chunks = [g.process({"speed": speed[i:i + 700], "force": force[i:i + 700]}, nonfinite="pass") for i in range(0, n, 700)]
    g.reset()
    stepped = [g.step({"speed": speed[i], "force": force[i]}) for i in range(200)]
    for key in whole:
        assert np.array_equal(whole[key], np.concatenate([c[key] for c in chunks]))
        assert np.array_equal(whole[key][:200], np.array([s[key] for s in stepped]))


def test_hard_cases_vertices_edges_hull(hard):
    ms, g = hard
    P = ms.points()
    tri = ms.triangles
    mids = np.concatenate([(P[tri[:, a]] + P[tri[:, b]]) / 2 for a, b in ((0, 1), (1, 2), (2, 0))])
    verts = P[in_range(ms)]
    out = g.run({"speed": np.concatenate([verts[:, 0], mids[:, 0]]), "force": np.concatenate([verts[:, 1], mids[:, 1]])})
    for i, m in enumerate(in_range(ms)):
        assert np.array_equal(out["ar"][i], lsf_to_poly_new(ms.ar_lsf[m]))
        assert np.allclose(out["ar"][i], ms.ar_coeff[m], rtol=0, atol=1e-12)
        assert np.abs(np.roots(out["ar"][i])).max() >= 0.995
    assert np.all(out["variance"] >= 0) and all(np.all(np.isfinite(v)) for v in out.values())
    for row in range(len(out["ar"])):
        assert np.abs(np.roots(out["ar"][row])).max() < 1.0
    # an edge midpoint is the average of the edge's two models (clamped ones excepted)
    k = len(verts)
    pairs = ((0, 1), (1, 2), (2, 0))  # the order of `mids` above
    checked = 0
    for j, (a, b) in enumerate(pairs):
        for t in range(len(tri)):
            i0, i1 = tri[t, a], tri[t, b]
            q = (P[i0] + P[i1]) / 2
            if not (0.05 <= q[0] < ms.max_speed and 0.05 <= q[1] < ms.max_force):
                continue
            row = k + j * len(tri) + t
            want = lsf_to_poly_reference(0.5 * ms.ma_lsf[i0] + 0.5 * ms.ma_lsf[i1])
            assert np.allclose(out["ma"][row], want, rtol=0, atol=1e-12)
            assert out["variance"][row] == pytest.approx(0.5 * (ms.variance[i0] + ms.variance[i1]), rel=1e-12, abs=1e-20)
            checked += 1
    assert checked >= 10


def test_hard_cases_saturated_query_outside_hull_projects_to_hull(hard):
    ms, g = hard
    out = g.step({"speed": 1e9, "force": 1e9})  # -> (219.99, 2.49), outside: the (220, 2.5) corner has no model
    P = ms.points()
    # The hull edge from (140, 2.5) to (220, 1.5) passes through the model at (180, 2.0): two boundary edges.
    idx = {tuple(pt): k for k, pt in enumerate(P)}
    A, M, B = (np.array(pt) for pt in ((140.0, 2.5), (180.0, 2.0), (220.0, 1.5)))
    scale = np.array([220.0, 2.5])
    q = np.array([219.99, 2.49]) / scale
    d = (B - A) / scale
    t = float(np.clip((q - A / scale) @ d / (d @ d), 0, 1))
    a, b, u = (idx[tuple(A)], idx[tuple(M)], 2 * t) if t < 0.5 else (idx[tuple(M)], idx[tuple(B)], 2 * t - 1)
    lsf = (1 - u) * ms.ar_lsf[a] + u * ms.ar_lsf[b]
    t = u
    assert np.allclose(out["ar"], lsf_to_poly_reference(lsf), rtol=0, atol=1e-11)
    assert out["variance"] == pytest.approx((1 - t) * ms.variance[a] + t * ms.variance[b], rel=1e-12)


def test_zero_variance_corners_silence_the_texture(hard):
    ms, g = hard
    out = g.run({"speed": np.array([0.0, 0.0, 100.0]), "force": np.array([0.0, 1.0, 0.0])})
    # queries clamp to (0.0001, 0.0001), (0.0001, 1.0), (100, 0.0001): next to the silent edge models, a measured
    # model's weight is at most 0.0001 / 0.5
    for i, q in enumerate([(0.0001, 0.0001), (0.0001, 1.0), (100.0, 0.0001)]):
        assert out["variance"][i] == pytest.approx(reference_model(ms, q)[3], rel=1e-12, abs=1e-20)
    assert np.all(out["variance"] <= 2e-4 * ms.variance.max())


@pytest.mark.parametrize("suffix, field", [(".xml", "(<SampleRate>)"), (".json", '("sample_rate")')])
def test_sample_rate_mismatch_refused(tmp_path, suffix, field):
    from flowtex.io.modelset import save_model_set

    name = tmp_path / f"Models_Rate Test{suffix}"
    path = write_hatt_xml(hard_model_set(), name) if suffix == ".xml" else save_model_set(hard_model_set(), name)
    with pytest.raises(GraphError) as err:
        load_graph(graph_file(tmp_path / "g", str(path), rate=2000))
    msg = str(err.value)
    assert "Models_Rate Test" in msg and f"1000 Hz {field}" in msg and "2000 Hz" in msg
    assert "flowtex models resample" in msg and "--rate 2000" in msg and "not supported" not in msg
    assert ("<SampleRate>" in msg) == (suffix == ".xml")  # the file's own field name, not the other format's
    assert "lookup.yaml:" in msg  # points at the graph file
    # the graph's rate from the command line (--set rate=...): the same graph file at the models' rate loads
    g = load_graph(graph_file(tmp_path / "g", str(path), rate=2000), {"rate": 1000})
    assert g.rate == 1000.0


def test_set_rate_parses_as_a_graph_level_override():
    from flowtex.graph.spec import parse_override

    assert parse_override("rate=2000") == ("rate", 2000)


@pytest.mark.parametrize("bad", [0, -5, "fast", True])
def test_set_rate_must_be_positive(tmp_path, bad):
    path = write_hatt_xml(hard_model_set(), tmp_path / "m.xml")
    with pytest.raises(GraphError, match=r"--set rate.*rate must be a number of Hz in \(0, 1e\+06\]"):
        load_graph(graph_file(tmp_path / "g", str(path)), {"rate": bad})


def test_missing_and_malformed_files_name_file_and_element(tmp_path):
    with pytest.raises(GraphError, match=r"Models_Not There\.xml: no such model file"):
        load_graph(graph_file(tmp_path / "a", "Models_Not There.xml"))
    (tmp_path / "b").mkdir()
    bad = write_hatt_xml(hard_model_set(), tmp_path / "b" / "Models_Broken One.xml")
    bad.write_text(bad.read_text().replace("<MAlsf", "<MAlsX").replace("</MAlsf>", "</MAlsX>"))
    with pytest.raises(GraphError, match=r"Models_Broken One\.xml: <model> modNum 1: missing <MAlsf>"):
        load_graph(graph_file(tmp_path / "b", "Models_Broken One.xml"))


def test_native_model_set_and_custom_clamping(tmp_path):
    ms = hard_model_set()
    save_model_set(ms, tmp_path / "hard set.json")
    g = load_graph(graph_file(tmp_path, "hard set.json", extra=", low_speed: 10.0, low_speed_value: 5.0"))
    out = g.run({"speed": np.array([7.0, 5.0]), "force": np.array([1.0, 1.0])})
    assert np.array_equal(out["ar"][0], out["ar"][1])  # 7 mm/s < low_speed -> 5 mm/s
    ar, ma, gain, var = reference_model(ms, (5.0, 1.0))
    assert np.allclose(out["ar"][0], ar, rtol=0, atol=1e-11) and out["gain"][0] == pytest.approx(gain, rel=1e-13)


def test_vertex_matches_stored_coefficients_to_file_precision(tmp_path):
    # A file written with 10 significant digits, like files from other software: the output at a vertex is
    # lsf_to_poly of the file's (rounded) LSFs, and agrees with the file's ARcoeff to the precision of the file.
    ms = cork_like_model_set()
    path = write_hatt_xml(ms, tmp_path / "Models_Ten Digits.xml", digits=10)
    g = load_graph(graph_file(tmp_path / "g", str(path)))
    for m in in_range(ms)[:6]:
        out = g.step({"speed": float(f"{ms.speeds[m]:.10g}"), "force": float(f"{ms.forces[m]:.10g}")})
        assert np.allclose(out["ar"], ms.ar_coeff[m], rtol=0, atol=1e-7)
        assert np.allclose(out["ma"], ms.ma_coeff[m], rtol=0, atol=1e-7)
        assert out["gain"] == float(f"{ms.gain[m]:.10g}")


def test_outside_is_validated(tmp_path):
    save_model_set(hard_model_set(), tmp_path / "hard set.json")
    with pytest.raises(GraphError, match="trend"):
        load_graph(graph_file(tmp_path, "hard set.json", outside="louder"))
