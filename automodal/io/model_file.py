"""The FE model file of ``automodal calibrate`` (HDF5, ``docs/calibrate.md``).

Layout: ``/mass`` and ``/stiffness`` (nominal, ``n x n``), one group per parameter under
``/parameters`` holding ``stiffness`` and/or ``mass`` (the part ``K_i``, ``M_i`` that the
parameter scales) and the attributes ``lower`` and ``upper``, ``/outputs/dof`` and
``/inputs/dof`` (0-based model DOF of each FRF channel, in the FRF file's order), and an
optional scalar ``/damping`` (the modal damping ratio of FE modes no test mode sets).

Every problem is refused in one line naming the file: shapes, non-finite or complex
values, asymmetric matrices, a mass that is not positive definite or a stiffness that is
indefinite (nominal, or at the parameters' lower bounds), DOF out of range, bounds that do
not hold 1.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import numpy as np

from automodal.core.fe_model import ParametrizedModel
from automodal.io.hdf5 import dataset, group, int_array, open_hdf5, real_array
from automodal.io.refusal import Refused, read_refusing

MAX_DOF = 4000
"""Largest model accepted: the calibration solves the dense eigenproblem at every step."""

MAX_PARAMETERS = 100
"""Most parameters accepted."""

DEFAULT_BOUNDS = (0.1, 10.0)
"""``lower`` and ``upper`` of a parameter that does not give them."""

SYMMETRY_TOLERANCE = 1e-8
"""Largest ``|A - A^T|`` accepted, relative to the largest ``|A|``."""

DEFINITE_TOLERANCE = 1e-9
"""A stiffness eigenvalue below ``-tol * max |eig|`` makes it indefinite."""


def read_model(path: str | os.PathLike[str]) -> ParametrizedModel:
    """Read and check an FE model file.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    ParametrizedModel

    Raises
    ------
    InputError
        One line naming the file, for every problem listed in the module text.
    """
    return read_refusing(_read, path)


def _read(path: Path, source: str) -> ParametrizedModel:
    with open_hdf5(path) as f:
        K0 = _matrix(f, "stiffness")
        n = K0.shape[0]
        M0 = _matrix(f, "mass", n)
        names, k_parts, m_parts, lower, upper = _parameters(f, n)
        outputs = _dofs(f, "outputs", n)
        inputs = _dofs(f, "inputs", n)
        damping = _damping(f)
    _check_definite(K0, M0, "the nominal model")
    if names:
        d = lower - 1.0
        _check_definite(K0 + np.tensordot(d, k_parts, axes=1),
                        M0 + np.tensordot(d, m_parts, axes=1), "the parameters' lower bounds")
    return ParametrizedModel(stiffness=K0, mass=M0, stiffness_parts=k_parts, mass_parts=m_parts,
                             names=tuple(names), lower=lower, upper=upper, outputs=outputs,
                             inputs=inputs, damping=damping)


def _matrix(parent: h5py.Group, name: str, n: int | None = None) -> np.ndarray:
    """A real, finite, symmetric square matrix (``n x n`` when ``n`` is given)."""
    label = f"{parent.name.rstrip('/')}/{name}"
    ds = dataset(parent, name)
    if ds is None:
        raise Refused(f"{label} is missing")
    if ds.ndim != 2 or ds.shape[0] != ds.shape[1]:
        raise Refused(f"{label} must be a square matrix, but has shape {ds.shape}")
    if n is None and ds.shape[0] > MAX_DOF:
        raise Refused(f"{label} is {ds.shape[0]} x {ds.shape[0]}: at most {MAX_DOF} DOF")
    if n is not None and ds.shape != (n, n):
        raise Refused(f"{label} has shape {ds.shape}, expected ({n}, {n}) like /stiffness")
    A = real_array(ds, label)
    if not np.all(np.isfinite(A)):
        raise Refused(f"{label} has values that are not finite")
    scale = float(np.max(np.abs(A)))
    if np.max(np.abs(A - A.T)) > SYMMETRY_TOLERANCE * scale:
        raise Refused(f"{label} is not symmetric")
    return 0.5 * (A + A.T)


def _parameters(
    f: h5py.File, n: int
) -> tuple[list[str], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Names, parts and bounds of every parameter (in the file's order of names)."""
    params = group(f, "parameters")
    if params is None or len(params) == 0:
        raise Refused("/parameters is missing or empty: give at least one parameter")
    names = list(params.keys())  # HDF5's order: by name
    if len(names) > MAX_PARAMETERS:
        raise Refused(f"/parameters has {len(names)} parameters: at most {MAX_PARAMETERS}")
    k_parts = np.zeros((len(names), n, n))
    m_parts = np.zeros((len(names), n, n))
    lower = np.empty(len(names))
    upper = np.empty(len(names))
    for i, name in enumerate(names):
        g = group(params, name)
        if g is None:
            raise Refused(f"/parameters/{name} must be a group")
        found = False
        for part, store in (("stiffness", k_parts), ("mass", m_parts)):
            if part in g:
                store[i] = _matrix(g, part, n)
                _check_semidefinite(store[i], f"/parameters/{name}/{part}")
                found = True
        if not found:
            raise Refused(f"/parameters/{name} has neither a stiffness nor a mass part")
        lower[i], upper[i] = _bounds(g, name)
    return names, k_parts, m_parts, lower, upper


def _bounds(g: h5py.Group, name: str) -> tuple[float, float]:
    """The attributes ``lower`` and ``upper`` (defaults :data:`DEFAULT_BOUNDS`)."""
    values = []
    for attr, default in zip(("lower", "upper"), DEFAULT_BOUNDS):
        raw = g.attrs.get(attr, default)
        try:
            value = float(np.asarray(raw).reshape(()))
        except (TypeError, ValueError):
            raise Refused(f"/parameters/{name} attribute {attr} must be one number") from None
        values.append(value)
    lo, hi = values
    if not (np.isfinite(lo) and np.isfinite(hi) and 0 < lo <= 1 <= hi and lo < hi):
        raise Refused(f"/parameters/{name} bounds [{lo:g}, {hi:g}] must satisfy"
                      " 0 < lower <= 1 <= upper (1 is the nominal value) and lower < upper")
    return lo, hi


def _dofs(f: h5py.File, side: str, n: int) -> np.ndarray:
    """``/<side>/dof``: 1-D non-empty integers in ``[0, n)``."""
    g = group(f, side)
    ds = None if g is None else dataset(g, "dof")
    if ds is None:
        raise Refused(f"/{side}/dof is missing (the 0-based model DOF of each FRF {side[:-1]})")
    dof = int_array(ds, f"/{side}/dof")
    if dof.ndim != 1 or dof.size == 0:
        raise Refused(f"/{side}/dof must be a non-empty 1-D list, but has shape {dof.shape}")
    bad = dof[(dof < 0) | (dof >= n)]
    if bad.size:
        raise Refused(f"/{side}/dof has DOF {int(bad[0])} out of range: the model has DOF"
                      f" 0..{n - 1} (0-based)")
    return dof


def _damping(f: h5py.File) -> float | None:
    """The optional scalar ``/damping`` in ``[0, 1)``."""
    ds = dataset(f, "damping")
    if ds is None:
        return None
    value = real_array(ds, "/damping")
    if value.size != 1 or not (np.isfinite(value).all() and 0 <= float(value.ravel()[0]) < 1):
        raise Refused("/damping must be one modal damping ratio in [0, 1)")
    return float(value.ravel()[0])


def _check_semidefinite(A: np.ndarray, label: str, allow_zero: bool = False) -> None:
    """Refuse a symmetric matrix with a clearly negative eigenvalue (and, unless
    ``allow_zero``, one of zeros only)."""
    eig = np.linalg.eigvalsh(A)
    top = float(np.max(np.abs(eig))) if eig.size else 0.0
    if top == 0.0:
        if allow_zero:
            return
        raise Refused(f"{label} is all zeros")
    if eig[0] < -DEFINITE_TOLERANCE * top:
        raise Refused(f"{label} is indefinite (eigenvalue {eig[0]:.3g}): it must be positive"
                      " semi-definite")


def _check_definite(K: np.ndarray, M: np.ndarray, where: str) -> None:
    """Refuse a mass that is not positive definite or an indefinite stiffness."""
    try:
        np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise Refused(f"the mass matrix of {where} is not positive definite") from None
    _check_semidefinite(K, f"the stiffness matrix of {where}", allow_zero=True)


def write_model(path: str | os.PathLike[str], model: ParametrizedModel) -> None:
    """Write ``model`` as a model file (for tests, benchmarks and examples); not atomic.

    Parameters
    ----------
    path : str or path-like
    model : ParametrizedModel
    """
    with h5py.File(path, "w") as f:
        f["stiffness"] = model.stiffness
        f["mass"] = model.mass
        params = f.create_group("parameters")
        for i, name in enumerate(model.names):
            g = params.create_group(name)
            if np.any(model.stiffness_parts[i]):
                g["stiffness"] = model.stiffness_parts[i]
            if np.any(model.mass_parts[i]):
                g["mass"] = model.mass_parts[i]
            g.attrs["lower"] = float(model.lower[i])
            g.attrs["upper"] = float(model.upper[i])
        f["outputs/dof"] = np.asarray(model.outputs, dtype=np.int64)
        f["inputs/dof"] = np.asarray(model.inputs, dtype=np.int64)
        if model.damping is not None:
            f["damping"] = float(model.damping)
