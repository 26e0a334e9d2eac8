"""Nodes take a loaded model set where they take its file: the same output bit for bit, nothing written to disk."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.errors import GraphError
from flowtex.graph.builder import GraphBuilder
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.registry import load_registry


def texture(models, rate=1000.0) -> GraphBuilder:
    return (GraphBuilder("texture", rate=rate, seed=1)
            .input("speed", unit="mm/s").input("force", unit="N")
            .node("lookup", "texture_lookup", models=models).node("synth", "arma_synth")
            .edge("speed -> lookup.speed").edge("force -> lookup.force")
            .edge("lookup.ar -> synth.ar").edge("lookup.ma -> synth.ma")
            .edge("lookup.gain -> synth.gain").edge("lookup.variance -> synth.variance")
            .output("accel", "synth.y"))


def test_texture_lookup_takes_the_loaded_set_as_its_file(tmp_path):
    ms = cork_like_model_set()
    path = save_model_set(ms, tmp_path / "cork.json")
    t = np.arange(2000) / 1000.0
    inputs = {"speed": 200.0 + 150.0 * np.sin(2 * np.pi * 0.7 * t), "force": 2.0 + 1.5 * np.sin(2 * np.pi * 0.3 * t)}
    from_file = texture(str(path)).build(tier="dispatch").run(inputs, seed=5)["accel"]
    # The object as the file reads back, and the object as made: a JSON model set keeps every float exactly.
    for obj in (load_model_set(path), ms):
        from_object = texture(obj).build(tier="dispatch").run(inputs, seed=5)["accel"]
        assert np.array_equal(from_object, from_file)
    assert np.std(from_file) > 0.0


def test_texture_lookup_object_at_another_rate_is_refused_by_name():
    ms = dataclasses.replace(cork_like_model_set(), sample_rate=2000.0)
    with pytest.raises(GraphError, match=r"GraphBuilder.node\('lookup', 'texture_lookup', models=...\): .*the model set "
                                         r"'cork-like' given in memory is for 2000 Hz but the graph runs at 1000 Hz"):
        texture(ms).resolve()


def test_friction_takes_the_loaded_set():
    ms = dataclasses.replace(cork_like_model_set(), mu=0.37)
    coulomb = load_registry().get("coulomb_friction")
    v = np.column_stack([np.linspace(-50, 50, 400), np.linspace(20, -20, 400), np.zeros(400)])
    f = np.linspace(0.0, 3.0, 400)
    want = coulomb.processor(mu=0.37)(velocity=v, normal_force=f)["force"]
    got = coulomb.processor(models=ms)(velocity=v, normal_force=f)["force"]
    assert np.array_equal(got, want)
    assert np.any(want != 0.0)


def _pattern():
    from flowtex.datasets.patterns import resonance
    from flowtex.models.patterns import Pattern

    b, a = resonance(180.0, 0.006, 1000.0)
    return Pattern(1000.0, np.array([1.0, 0.0, 0.0]), np.zeros(3), np.array([2.0, 4.0, 6.0]), np.array([10.0, 7.0, 12.0]),
                   [b] * 3, [a] * 3)


def test_pattern_and_tap_nodes_read_their_file_into_the_object_they_take(tmp_path):
    # The file is read at the graph/io boundary into the object the node takes: a node given the object renders
    # the same samples as one given the file (both file formats keep every float exactly).
    from flowtex.datasets.taps import synthetic_tap_library
    from flowtex.io.patternfile import write_pattern
    from flowtex.io.taplib import write_tap_library

    types = load_registry().types
    pat = _pattern()
    x = np.column_stack([np.linspace(1.0, 8.0, 600), np.zeros(600), np.zeros(600)])
    runs = [types["patterned_texture"].processor(pattern=p)(position=x)["y"]
            for p in (pat, str(write_pattern(tmp_path / "p.json", pat)))]
    assert np.array_equal(runs[0], runs[1]) and np.count_nonzero(runs[0]) > 100

    lib = synthetic_tap_library()
    contact = (np.arange(600) % 200 >= 50).astype(float)
    speed = np.full(600, 80.0)
    runs = [types["tap_player"].processor(library=v)(in_contact=contact, incoming_speed=speed)["force"]
            for v in (lib, str(write_tap_library(tmp_path / "t.json", lib)))]
    assert np.array_equal(runs[0], runs[1]) and np.count_nonzero(runs[0]) > 100


def test_a_path_reaches_the_node_as_the_loaded_object_and_its_file(tmp_path):
    # Node.processor with a path goes through the same loader as a graph: the node's constructor receives the
    # model set, and the file it came from only for its messages.
    ms = cork_like_model_set()
    path = save_model_set(ms, tmp_path / "cork.json")
    proc = load_registry().types["texture_lookup"].processor(models=str(path))
    assert isinstance(proc.node.p["models"], type(ms)) and proc.context.files == {"models": path}
    assert np.array_equal(proc.node.model_set.ar_lsf, ms.ar_lsf)
    in_memory = load_registry().types["texture_lookup"].processor(models=ms)
    assert in_memory.context.files == {} and in_memory.node.p["models"] is ms


def test_every_object_parameter_of_a_builtin_node_has_a_reader_returning_its_type(tmp_path):
    # OBJECT_FORMATS names each type by module:class: a type moved or renamed without its entry would silently turn
    # a graph file's path into a Path handed to the node.
    from flowtex.datasets.taps import synthetic_tap_library
    from flowtex.io.formats import object_reader
    from flowtex.io.patternfile import write_pattern
    from flowtex.io.taplib import write_tap_library

    files = {"TextureModelSet": save_model_set(cork_like_model_set(), tmp_path / "m.json"),
             "Pattern": write_pattern(tmp_path / "p.json", _pattern()),
             "TapLibrary": write_tap_library(tmp_path / "t.json", synthetic_tap_library())}
    seen = set()
    for cls in load_registry().types.values():
        for name, decl in cls.params.items():
            if decl.kind == "path" and decl.objects:
                reader = object_reader(decl.objects)
                assert reader is not None, f"{cls.type_name}.{name}: no reader for {decl.objects}"
                kind = decl.objects[0].__name__
                assert isinstance(reader(files[kind]), decl.objects)
                seen.add((cls.type_name, name))
    assert seen == {("texture_lookup", "models"), ("coulomb_friction", "models"), ("dahl_friction", "models"),
                    ("patterned_texture", "pattern"), ("tap_player", "library")}


def test_an_unreadable_file_is_named_by_its_parameter_in_a_graph_and_in_a_processor(tmp_path):
    from flowtex.errors import ParamError

    missing = tmp_path / "nowhere.json"
    with pytest.raises(ParamError, match=f"^node type 'coulomb_friction' processor: parameter 'models': "
                                         f"{re.escape(str(missing))}: no such model file$") as err:
        load_registry().types["coulomb_friction"].processor(models=str(missing))
    assert err.value.param == "models"
    with pytest.raises(GraphError, match=rf"GraphBuilder.node\('lookup', 'texture_lookup', models=...\): node 'lookup' "
                                         rf"\(texture_lookup\): {missing}: no such model file"):
        texture(str(missing)).resolve()


def test_a_pattern_or_tap_library_in_memory_at_another_rate_is_refused_by_what_it_is():
    from flowtex.datasets.taps import synthetic_tap_library
    from flowtex.errors import ParamError

    types = load_registry().types
    with pytest.raises(ParamError, match="^node type 'patterned_texture' processor: parameter 'pattern': "
                                         "the pattern given in memory: pattern filters are sampled at 1000 Hz but this node "
                                         "runs at 2000 Hz"):
        types["patterned_texture"].processor(rate=2000.0, pattern=_pattern())(position=np.zeros((4, 3)))
    with pytest.raises(ParamError, match=r"^node type 'tap_player' processor: parameter 'library': "
                                         r"the tap library given in memory is sampled at 1000 Hz but this node runs at 2000 Hz; "
                                         r"resample it \(flowtex.models.taps.resample_tap_library\)"):
        types["tap_player"].processor(rate=2000.0, library=synthetic_tap_library())(in_contact=np.zeros(4), incoming_speed=np.zeros(4))
