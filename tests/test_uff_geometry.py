"""Issue 15 (item 7): node coordinates from UFF datasets 15 and 2411, given with --geometry
or carried by the FRF file itself, matched to the channels' node numbers; and refusals."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
import pyuff

from automodal.errors import InputError
from automodal.io.frf_file import read_frf
from automodal.io.geometry import read_geometry
from automodal.io.uff import read_uff

FREQ = np.linspace(1.0, 50.0, 40)
IDENTITY = np.vstack([np.eye(3), np.zeros(3)])


def nodes_set(kind: int, nums: list[int], xyz: np.ndarray, cs: int | list[int] = 0,
              disp_cs: int | list[int] = 0) -> dict[str, Any]:
    """A dataset 15 or 2411 dict for the nodes ``nums`` at the rows of ``xyz``."""
    n = len(nums)
    def_cs = cs if isinstance(cs, list) else [cs] * n
    disp = disp_cs if isinstance(disp_cs, list) else [disp_cs] * n
    prepare = pyuff.prepare_15 if kind == 15 else pyuff.prepare_2411
    return prepare(node_nums=nums, def_cs=def_cs, disp_cs=disp, color=[1] * n,
                   x=list(xyz[:, 0]), y=list(xyz[:, 1]), z=list(xyz[:, 2]),
                   return_full_dict=True)


def systems_set(labels: list[int], matrices: list[np.ndarray]) -> dict[str, Any]:
    """A dataset 2420 (coordinate systems, all cartesian)."""
    n = len(labels)
    return pyuff.prepare_2420(Part_UID=1, Part_Name="part", CS_sys_labels=labels,
                              CS_types=[0] * n, CS_colors=[8] * n,
                              CS_names=[f"cs{k}" for k in labels], CS_matrices=matrices,
                              return_full_dict=True)


def frf_set(rsp: int, ref: int, data: np.ndarray, rsp_dir: int = 3,
            ref_dir: int = 3) -> dict[str, Any]:
    """A dataset 58 accelerance from (rsp, +Z) per (ref, +Z)."""
    return pyuff.prepare_58(rsp_node=rsp, rsp_dir=rsp_dir, ref_node=ref, ref_dir=ref_dir,
                            data=data, x=FREQ, binary=0, func_type=4, abscissa_spacing=1,
                            abscissa_spec_data_type=18, ordinate_spec_data_type=12,
                            orddenom_spec_data_type=13)


def write(path: Path, sets: list[dict[str, Any]]) -> Path:
    path.unlink(missing_ok=True)
    pyuff.UFF(str(path)).write_sets(sets, mode="add")
    return path


def frfs(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [rng.standard_normal(FREQ.size) + 1j * rng.standard_normal(FREQ.size)
            for _ in range(n)]


XYZ = np.array([[0.0, 0.0, 0.0], [0.25, 0.0, 0.0], [0.5, 0.1, 0.0], [0.75, 0.0, 0.2]])


def refused(call, *words: str) -> str:
    with pytest.raises(InputError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message
    return message


# ------------------------------------------------------------------- --geometry file.uff


@pytest.mark.parametrize("kind", [15, 2411])
def test_geometry_file_gives_the_nodes(tmp_path, kind):
    path = write(tmp_path / "nodes.unv", [nodes_set(kind, [11, 12, 13, 14], XYZ)])
    geometry = read_geometry(path)  # by the suffix
    assert sorted(geometry.nodes) == [11, 12, 13, 14]
    np.testing.assert_allclose([geometry.nodes[k] for k in (11, 12, 13, 14)], XYZ)
    assert geometry.channels == {}
    nodes, directions, xyz = geometry.locate(["a", "b"], [14, 12], ["+Z", "-Y"])
    assert nodes == [14, 12] and directions == ["+Z", "-Y"]
    np.testing.assert_allclose(xyz, XYZ[[3, 1]])


def test_geometry_from_both_datasets_and_an_identity_system(tmp_path):
    # nodes 1-2 in dataset 15, 3-4 in dataset 2411 under system 1, which a dataset 2420
    # defines as the global system (identity, no offset): all four are read
    path = write(tmp_path / "both.uff", [
        systems_set([1], [IDENTITY]),
        nodes_set(15, [1, 2], XYZ[:2]),
        nodes_set(2411, [3, 4], XYZ[2:], cs=1, disp_cs=1),
    ])
    geometry = read_geometry(path)
    np.testing.assert_allclose([geometry.nodes[k] for k in (1, 2, 3, 4)], XYZ)


@pytest.mark.parametrize("sets, words", [
    ([nodes_set(15, [1, 2, 1], XYZ[:3])], ("node 1 is given twice",)),
    ([nodes_set(15, [1, 2], XYZ[:2]), nodes_set(2411, [2, 3], XYZ[2:])],
     ("node 2 is given twice", "data sets 1 and 2")),
    ([nodes_set(15, [1, 2], XYZ[:2], cs=[0, 3])], ("node 2", "coordinate system 3", "global")),
    ([nodes_set(2411, [1], XYZ[:1], disp_cs=2)], ("displacements", "coordinate system 2")),
    # system 1 defined, but shifted: not the global system
    ([systems_set([1], [np.vstack([np.eye(3), [1.0, 0.0, 0.0]])]),
      nodes_set(15, [1], XYZ[:1], cs=1)], ("coordinate system 1",)),
    ([frf_set(1, 2, frfs(1)[0])], ("no node coordinates", "58")),
])
def test_geometry_file_refusals(tmp_path, sets, words):
    path = write(tmp_path / "bad.uff", sets)
    message = refused(lambda: read_geometry(path), *words)
    assert str(path) in message


def test_geometry_file_refuses_an_unreadable_file(tmp_path):
    path = tmp_path / "text.uff"
    path.write_text("not a universal file\n")
    refused(lambda: read_geometry(path), str(path))


# ------------------------------------------------------------ geometry in the FRF file


def test_frf_file_places_its_outputs_by_node(tmp_path):
    # two responses (nodes 4 and 2) x one reference (node 1); nodes listed out of order
    h = frfs(2)
    path = write(tmp_path / "with_nodes.uff", [
        nodes_set(15, [3, 1, 4, 2], XYZ),
        frf_set(4, 1, h[0]), frf_set(2, 1, h[1]),
    ])
    data = read_uff(path)
    assert list(data.output_nodes) == [4, 2]
    np.testing.assert_allclose(data.output_xyz, XYZ[[2, 3]])
    assert "15/2411" in data.attributes["geometry_source"]


def test_frf_file_without_nodes_has_no_coordinates(tmp_path):
    data = read_uff(write(tmp_path / "bare.uff", [frf_set(4, 1, frfs(1)[0])]))
    assert data.output_xyz is None
    assert "geometry_source" not in data.attributes


@pytest.mark.parametrize("rsp, ref, side", [(5, 1, "response node 5"),
                                            (2, 9, "reference node 9")])
def test_frf_file_refuses_a_node_missing_from_its_geometry(tmp_path, rsp, ref, side):
    path = write(tmp_path / "partial.uff", [
        nodes_set(2411, [1, 2, 3], XYZ[:3]), frf_set(rsp, ref, frfs(1)[0])])
    refused(lambda: read_uff(path), side, "dataset 15/2411", str(path))


def test_frf_file_refuses_duplicate_nodes_and_other_systems(tmp_path):
    h = frfs(1)[0]
    twice = write(tmp_path / "twice.uff", [nodes_set(15, [1, 2, 2], XYZ[:3]), frf_set(2, 1, h)])
    refused(lambda: read_uff(twice), "node 2 is given twice")
    local = write(tmp_path / "local.uff", [nodes_set(15, [1, 2], XYZ[:2], cs=4),
                                           frf_set(2, 1, h)])
    refused(lambda: read_uff(local), "coordinate system 4")


# ----------------------------------------------------------------------------- commands


def cli(*args: str) -> subprocess.CompletedProcess:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run([sys.executable, "-m", "automodal", *args], capture_output=True,
                          text=True, env=env, timeout=300)


@pytest.fixture(scope="module")
def hammer_uff(tmp_path_factory) -> Path:
    """A simulated roving-hammer test (one response, four hammer points) as UFF 58, with
    its nodes in a dataset 2411."""
    folder = tmp_path_factory.mktemp("uffgeo")
    sim = folder / "sim.h5"
    done = cli("simulate", str(sim), "--dof", "4", "--outputs", "1", "--inputs", "1-4",
               "--lines", "300", "--quantity", "acceleration", "--seed", "3", "-q")
    assert done.returncode == 0, done.stderr
    data = read_frf(sim)
    sets: list[dict[str, Any]] = [nodes_set(2411, [10, 20, 30, 40], XYZ)]
    for j in range(data.n_inputs):
        s = pyuff.prepare_58(rsp_node=10, rsp_dir=3, ref_node=10 * (j + 1), ref_dir=3,
                             data=data.frf[:, 0, j], x=data.frequency, binary=0, func_type=4,
                             abscissa_spacing=1, abscissa_spec_data_type=18,
                             ordinate_spec_data_type=12, orddenom_spec_data_type=13)
        sets.append(s)
    return write(folder / "hammer.uff", sets)


def test_identify_places_the_shapes_from_the_uff_nodes(hammer_uff, tmp_path):
    report = tmp_path / "r.json"
    done = cli("identify", str(hammer_uff), "-o", str(report), "--bootstrap", "10",
               "--quiet", "--jobs", "1")
    assert done.returncode == 0, done.stderr
    inp = json.loads(report.read_text())["input"]
    # reciprocity: the shape channels are the hammer points, placed by the file's nodes
    assert inp["mode_shape_nodes"] == [10, 20, 30, 40]
    np.testing.assert_allclose(inp["mode_shape_xyz"], XYZ)


def test_convert_writes_the_uff_nodes_and_geometry_uff_overrides(hammer_uff, tmp_path):
    out = tmp_path / "c.h5"
    done = cli("convert", str(hammer_uff), str(out), "-q")
    assert done.returncode == 0, done.stderr
    with h5py.File(out, "r") as f:
        np.testing.assert_allclose(f["outputs/xyz"][()], XYZ[:1])
    moved = write(tmp_path / "moved.unv", [nodes_set(15, [10, 20, 30, 40], XYZ + 1.0)])
    again = tmp_path / "d.h5"
    done = cli("convert", str(hammer_uff), str(again), "--geometry", str(moved), "-q")
    assert done.returncode == 0, done.stderr
    with h5py.File(again, "r") as f:
        np.testing.assert_allclose(f["outputs/xyz"][()], XYZ[:1] + 1.0)


def test_geometry_uff_without_a_channel_node_is_one_line(hammer_uff, tmp_path):
    few = write(tmp_path / "few.uff", [nodes_set(15, [20, 30], XYZ[:2])])
    out = tmp_path / "c.h5"
    done = cli("convert", str(hammer_uff), str(out), "--geometry", str(few))
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "node 10" in done.stderr
    assert not out.exists()


def test_identify_of_a_uff_file_loads_no_hdf5_library(hammer_uff, tmp_path):
    """h5py is for HDF5 inputs and reports: a UFF input with a JSON report does without
    it (the reading runs in a forked child, whose imports do not count here)."""
    report = tmp_path / "r.json"
    code = (
        "import sys\n"
        "from automodal.cli import main\n"
        "try:\n"
        f"    main(['identify', {str(hammer_uff)!r}, '-o', {str(report)!r}, '--bootstrap',"
        " '4', '--quiet'])\n"
        "except SystemExit as exc:\n"
        "    assert exc.code == 0, exc.code\n"
        "print(','.join(m for m in ('h5py', 'matplotlib', 'dask') if m in sys.modules))\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "", f"imported: {done.stdout.strip()}"
    assert report.is_file()
