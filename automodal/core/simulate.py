"""Synthetic vibration tests of known lumped-mass systems.

Pure numerical functions: build mass, stiffness and damping matrices, compute the exact
modes and frequency response functions, add measurement noise. Nothing here reads or
writes files or prints.

DOF indices in this module are 0-based (the command line uses 1-based numbers).

Conventions
-----------
A mode's pole is ``lambda = -zeta * omega + j * omega * sqrt(1 - zeta**2)`` with
``Im lambda > 0``; its natural frequency is ``|lambda| / (2 pi)`` in Hz and its damping
ratio ``-Re lambda / |lambda|``. The receptance is ``H(w) = (K - w^2 M + j w C)^-1``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg

from automodal.core.modal import unit_max_shapes
from automodal.core.synthesis import quantity_factor
from automodal.frfdata import QUANTITIES, FRFData
from automodal.quantities import quantity_power

NOISE_KINDS = ("proportional", "additive")
"""Kinds of measurement noise that :func:`add_noise` can add."""

DAMPING_KINDS = ("rayleigh", "nonproportional")
"""Kinds of damping that :func:`damp` can build."""

_CHUNK_BYTES = 1 << 22  # ~4 MB of dynamic-stiffness matrices per batched solve

IndexLike = int | Sequence[int] | np.ndarray | None
RngLike = np.random.Generator | int | None


@dataclass
class MechanicalSystem:
    """A linear lumped-mass system ``M q'' + C q' + K q = f``.

    Attributes
    ----------
    M, K, C : ndarray, shape (n_dof, n_dof)
        Mass, stiffness and viscous damping matrices (float).
    xyz : ndarray, shape (n_dof, 3), or None
        Coordinates of the DOFs, for mode-shape plots.
    meta : dict
        How the system was built (kind, parameters, damping); JSON-friendly values.
    """

    M: np.ndarray
    K: np.ndarray
    C: np.ndarray
    xyz: np.ndarray | None = None
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.M = np.asarray(self.M, dtype=float)
        self.K = np.asarray(self.K, dtype=float)
        self.C = np.asarray(self.C, dtype=float)
        n = self.M.shape[0]
        for name in ("M", "K", "C"):
            if getattr(self, name).shape != (n, n):
                raise ValueError(f"{name} must be ({n}, {n}), got {getattr(self, name).shape}")
        if self.xyz is not None:
            self.xyz = np.asarray(self.xyz, dtype=float).reshape(n, 3)

    @property
    def n_dof(self) -> int:
        """Number of degrees of freedom."""
        return int(self.M.shape[0])


@dataclass
class Modes:
    """Modes of a system (or of a model), one per conjugate pole pair.

    Attributes
    ----------
    poles : ndarray, shape (n_modes,), complex
        Poles with ``Im > 0`` in rad/s, sorted by natural frequency.
    frequency_hz : ndarray, shape (n_modes,)
        Undamped natural frequencies ``|lambda| / (2 pi)``.
    damping_ratio : ndarray, shape (n_modes,)
        ``-Re lambda / |lambda|``.
    shapes : ndarray, shape (n_outputs, n_modes), complex
        Displacement mode shapes at the sensor DOFs, each column scaled so that its
        largest-magnitude entry is ``1 + 0j``.
    residues : ndarray, shape (n_modes, n_outputs, n_inputs), complex, or None
        Receptance residues ``R_r``: ``H(s) = sum_r R_r / (s - lambda_r) + conj(R_r) /
        (s - conj(lambda_r))`` (when the inputs were given).
    """

    poles: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray
    shapes: np.ndarray
    residues: np.ndarray | None = None

    @classmethod
    def from_poles(
        cls, poles: np.ndarray, shapes: np.ndarray, residues: np.ndarray | None = None
    ) -> Modes:
        """Build from poles (``Im > 0``) and shapes; frequencies and damping follow."""
        poles = np.asarray(poles, dtype=complex).reshape(-1)
        mag = np.abs(poles)
        zeta = -poles.real / np.where(mag > 0, mag, 1.0)
        shapes = np.asarray(shapes, dtype=complex)
        if shapes.ndim != 2 or shapes.shape[1] != poles.size:
            raise ValueError(f"shapes must be (n_outputs, {poles.size}), got {shapes.shape}")
        return cls(poles, mag / (2.0 * np.pi), zeta, shapes, residues)

    @classmethod
    def empty(cls, n_outputs: int, n_inputs: int | None = None) -> Modes:
        """No mode at all (e.g. the truth of a pure-noise test)."""
        res = None if n_inputs is None else np.zeros((0, n_outputs, n_inputs), dtype=complex)
        return cls.from_poles(np.zeros(0, complex), np.zeros((n_outputs, 0), complex), res)

    @property
    def n_modes(self) -> int:
        """Number of modes."""
        return int(self.poles.size)

    @property
    def n_outputs(self) -> int:
        """Number of sensor DOFs in the shapes."""
        return int(self.shapes.shape[0])


@dataclass
class StateSpace:
    """A continuous-time model ``x' = A x + B u``, ``y = C x + D u``.

    Unpacks as ``A, B, C, D = state_space(...)``.
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray

    def __iter__(self):
        return iter((self.A, self.B, self.C, self.D))


# --------------------------------------------------------------------------- systems


def _per_element(
    value: float | Sequence[float] | np.ndarray, n: int, name: str, positive: bool = False
) -> np.ndarray:
    """A scalar broadcast to ``n`` elements, or an array checked to have ``n`` elements,
    all finite and >= 0 (> 0 with ``positive``).
    """
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    arr = arr.reshape(-1)
    if arr.size != n:
        raise ValueError(f"{name} needs {n} values, got {arr.size}")
    if np.any(arr <= 0 if positive else arr < 0) or not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite and {'>' if positive else '>='} 0")
    return arr


def _spring_matrix(
    n: int, pairs: np.ndarray, k: np.ndarray, ground: np.ndarray
) -> np.ndarray:
    """Stiffness (or dashpot) matrix of springs ``k`` between DOF ``pairs`` and to ground."""
    K = np.diag(ground.astype(float))
    for (i, j), kij in zip(pairs, k, strict=True):
        K[i, i] += kij
        K[j, j] += kij
        K[i, j] -= kij
        K[j, i] -= kij
    return K


def chain(
    n_dof: int,
    mass: float | Sequence[float] | np.ndarray = 1.0,
    stiffness: float | Sequence[float] | np.ndarray = 1e4,
    grounded: bool = True,
    spacing: float = 1.0,
) -> MechanicalSystem:
    """A spring-mass chain (undamped; see :func:`damp`).

    Parameters
    ----------
    n_dof : int
        Number of masses.
    mass : float or array of n_dof
        Masses (kg).
    stiffness : float or array
        Spring stiffnesses (N/m). With ``grounded`` there are ``n_dof`` springs, the first
        between ground and mass 0, spring ``i`` between masses ``i - 1`` and ``i``;
        otherwise ``n_dof - 1`` springs between neighbours (free-free chain, one rigid-body
        mode at 0 Hz).
    grounded : bool
        Attach the first mass to ground.
    spacing : float
        Distance between masses along x, for the coordinates.

    Returns
    -------
    MechanicalSystem
    """
    if n_dof < 1:
        raise ValueError("a chain needs at least one mass")
    m = _per_element(mass, n_dof, "mass", positive=True)
    n_springs = n_dof if grounded else n_dof - 1
    k = _per_element(stiffness, n_springs, "stiffness")
    ground = np.zeros(n_dof)
    if grounded:
        ground[0] = k[0]
        k = k[1:]
    pairs = np.column_stack([np.arange(n_dof - 1), np.arange(1, n_dof)])
    xyz = np.column_stack([spacing * np.arange(n_dof), np.zeros(n_dof), np.zeros(n_dof)])
    meta = {"kind": "chain", "name": f"{n_dof}-DOF chain", "n_dof": n_dof,
            "grounded": bool(grounded), "mass": _scalar_or_list(mass),
            "stiffness": _scalar_or_list(stiffness)}
    return MechanicalSystem(np.diag(m), _spring_matrix(n_dof, pairs, k, ground),
                            np.zeros((n_dof, n_dof)), xyz, meta)


def grid(
    nx: int,
    ny: int,
    mass: float | Sequence[float] | np.ndarray = 1.0,
    kx: float = 1e4,
    ky: float | None = None,
    ground: float | Sequence[float] | np.ndarray | None = None,
    symmetric: bool = False,
    spacing: tuple[float, float] = (1.0, 1.0),
) -> MechanicalSystem:
    """A 2-D grid of ``nx * ny`` masses moving out of plane (undamped; see :func:`damp`).

    DOF ``ix + nx * iy`` is the mass at column ``ix``, row ``iy``. Springs ``kx`` join
    neighbours along x, ``ky`` along y, and every mass has a spring to ground.

    Parameters
    ----------
    nx, ny : int
        Masses along x and y.
    mass : float or array of nx*ny
        Masses (kg).
    kx : float
        Springs between x-neighbours (N/m).
    ky : float, optional
        Springs between y-neighbours. Default ``0.45 * kx`` (distinct, well separated
        modes), or ``kx`` with ``symmetric``.
    ground : float or array of nx*ny, optional
        Springs to ground. Default ``0.1 * kx`` at every mass.
    symmetric : bool
        ``ky = kx``: a square grid then has repeated modes, a nearly square one close modes.
    spacing : (dx, dy)
        Distances between masses, for the coordinates.

    Returns
    -------
    MechanicalSystem
    """
    if nx < 1 or ny < 1:
        raise ValueError("a grid needs nx, ny >= 1")
    if ky is None:
        ky = kx if symmetric else 0.45 * kx
    n = nx * ny
    m = _per_element(mass, n, "mass", positive=True)
    g = _per_element(0.1 * kx if ground is None else ground, n, "ground")
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny))
    ix, iy = ix.ravel(), iy.ravel()
    dof = ix + nx * iy
    along_x = np.column_stack([dof[ix < nx - 1], dof[ix < nx - 1] + 1])
    along_y = np.column_stack([dof[iy < ny - 1], dof[iy < ny - 1] + nx])
    pairs = np.vstack([along_x, along_y])
    k = np.concatenate([np.full(len(along_x), kx), np.full(len(along_y), ky)])
    xyz = np.column_stack([spacing[0] * ix, spacing[1] * iy, np.zeros(n)])
    meta = {"kind": "grid", "name": f"{nx}x{ny} grid", "nx": nx, "ny": ny,
            "mass": _scalar_or_list(mass), "kx": kx, "ky": ky,
            "ground": _scalar_or_list(0.1 * kx if ground is None else ground)}
    return MechanicalSystem(np.diag(m), _spring_matrix(n, pairs, k, g), np.zeros((n, n)),
                            xyz, meta)


def combine(*systems: MechanicalSystem) -> MechanicalSystem:
    """Uncoupled systems side by side (block-diagonal matrices), e.g. two identical chains.

    The DOFs of the second system follow those of the first, and so on; coordinates are
    offset along y so that the parts do not overlap in plots.
    """
    if not systems:
        raise ValueError("nothing to combine")
    xyz = None
    if all(s.xyz is not None for s in systems):
        parts, offset = [], 0.0
        for s in systems:
            parts.append(s.xyz + [0.0, offset - s.xyz[:, 1].min(), 0.0])
            offset = parts[-1][:, 1].max() + 1.0
        xyz = np.vstack(parts)
    return MechanicalSystem(
        scipy.linalg.block_diag(*(s.M for s in systems)),
        scipy.linalg.block_diag(*(s.K for s in systems)),
        scipy.linalg.block_diag(*(s.C for s in systems)),
        xyz,
        {"kind": "combined", "name": " + ".join(s.meta.get("name", "system") for s in systems),
         "parts": [s.meta for s in systems]},
    )


def _scalar_or_list(value: Any) -> Any:
    """A JSON-friendly copy of a parameter that may be a scalar or an array."""
    arr = np.asarray(value, dtype=float)
    return float(arr) if arr.ndim == 0 else arr.tolist()


# --------------------------------------------------------------------------- damping


def rayleigh(M: np.ndarray, K: np.ndarray, alpha: float, beta: float) -> np.ndarray:
    """Proportional (Rayleigh) damping ``C = alpha M + beta K``.

    A mode at ``omega`` gets ``zeta = alpha / (2 omega) + beta omega / 2``.
    """
    return alpha * np.asarray(M, dtype=float) + beta * np.asarray(K, dtype=float)


def rayleigh_coefficients(
    f1_hz: float, f2_hz: float, zeta1: float, zeta2: float | None = None
) -> tuple[float, float]:
    """The ``(alpha, beta)`` that give damping ratio ``zeta1`` at ``f1_hz`` and ``zeta2``
    (default ``zeta1``) at ``f2_hz``. Between the two, damping is lower; outside, higher.
    """
    zeta2 = zeta1 if zeta2 is None else zeta2
    w1, w2 = 2.0 * np.pi * f1_hz, 2.0 * np.pi * f2_hz
    if w1 <= 0 or w2 <= 0:
        raise ValueError("Rayleigh anchor frequencies must be > 0")
    if np.isclose(w1, w2):
        zeta = 0.5 * (zeta1 + zeta2)
        return float(zeta * w1), float(zeta / w1)
    # [1/(2 w1), w1/2; 1/(2 w2), w2/2] [alpha; beta] = [zeta1; zeta2]
    alpha, beta = np.linalg.solve([[0.5 / w1, 0.5 * w1], [0.5 / w2, 0.5 * w2]], [zeta1, zeta2])
    return float(alpha), float(beta)


def dashpots(
    n_dof: int,
    connections: Sequence[tuple[int, int | None]],
    coefficients: float | Sequence[float] | np.ndarray,
) -> np.ndarray:
    """Damping matrix of discrete viscous dashpots (non-proportional in general).

    Parameters
    ----------
    n_dof : int
        Size of the system.
    connections : sequence of (i, j)
        0-based DOFs joined by each dashpot; ``j = None`` means to ground.
    coefficients : float or array
        Dashpot constants (N s/m), one per connection or one for all.

    Returns
    -------
    ndarray, shape (n_dof, n_dof)
    """
    c = _per_element(coefficients, len(connections), "coefficients")
    ground = np.zeros(n_dof)
    pairs, c_pairs = [], []
    for (i, j), cij in zip(connections, c, strict=True):
        _check_dofs([i] if j is None else [i, j], n_dof, "dashpot DOF")
        if j is None:
            ground[i] += cij
        else:
            pairs.append((i, j))
            c_pairs.append(cij)
    return _spring_matrix(n_dof, np.array(pairs, dtype=int).reshape(-1, 2),
                          np.array(c_pairs), ground)


def undamped_modes(system: MechanicalSystem) -> tuple[np.ndarray, np.ndarray]:
    """Natural angular frequencies and mass-normalised shapes of the undamped system.

    Returns
    -------
    omega : ndarray, shape (n_dof,)
        Ascending, rad/s (rigid-body modes at 0).
    phi : ndarray, shape (n_dof, n_dof)
        Columns with ``phi.T M phi = I``.
    """
    lam, phi = scipy.linalg.eigh(system.K, system.M)
    return np.sqrt(np.clip(lam, 0.0, None)), phi


def natural_frequencies_hz(system: MechanicalSystem) -> np.ndarray:
    """Undamped natural frequencies in Hz, ascending."""
    return undamped_modes(system)[0] / (2.0 * np.pi)


def damp(
    system: MechanicalSystem,
    kind: str = "rayleigh",
    zeta: float = 0.01,
    connections: Sequence[tuple[int, int | None]] | None = None,
) -> MechanicalSystem:
    """The system with damping of a chosen kind and level (its own ``C`` is replaced).

    Parameters
    ----------
    system : MechanicalSystem
    kind : {"rayleigh", "nonproportional"}
        ``"rayleigh"``: ``C = alpha M + beta K`` with damping ratio ``zeta`` at the lowest and
        the highest (non-zero) natural frequency, less in between.
        ``"nonproportional"``: Rayleigh damping at ``zeta / 2`` plus discrete dashpots at
        ``connections``, scaled so that the largest modal damping ratio they add (to first
        order) is ``zeta``; the modes become complex.
    zeta : float
        Damping level.
    connections : sequence of (i, j), optional
        Dashpot places for ``"nonproportional"``; default: to ground at the last DOF and
        at DOF ``n_dof // 2``.

    Returns
    -------
    MechanicalSystem
        A copy with the new ``C``; ``meta["damping"]`` records the parameters.
    """
    if kind not in DAMPING_KINDS:
        raise ValueError(f"damping kind must be one of {DAMPING_KINDS}, got {kind!r}")
    if not 0 <= zeta < 1:
        raise ValueError("zeta must be in [0, 1)")
    omega, phi = undamped_modes(system)
    flexible = omega > 1e-9 * max(omega.max(), 1.0)
    if not flexible.any():
        raise ValueError("the system has no flexible mode to damp")
    omega, phi = omega[flexible], phi[:, flexible]
    f_lo, f_hi = omega[0] / (2 * np.pi), omega[-1] / (2 * np.pi)
    base = zeta if kind == "rayleigh" else 0.5 * zeta
    alpha, beta = rayleigh_coefficients(f_lo, f_hi, base)
    C = rayleigh(system.M, system.K, alpha, beta)
    info: dict[str, Any] = {"kind": kind, "zeta": zeta, "alpha": alpha, "beta": beta}
    if kind == "nonproportional":
        n = system.n_dof
        if connections is None:
            connections = [(n - 1, None)] + ([(n // 2, None)] if n > 2 else [])
        unit = dashpots(n, connections, 1.0)
        added = np.einsum("ir,ij,jr->r", phi, unit, phi) / (2 * omega)
        scale = zeta / added.max() if added.max() > 0 else 0.0
        C = C + scale * unit
        info["dashpots"] = [[int(i), None if j is None else int(j)] for i, j in connections]
        info["dashpot_coefficient"] = float(scale)
    return replace(system, C=C, meta={**system.meta, "damping": info})


# --------------------------------------------------------------------------- responses


def _check_dofs(idx: Sequence[int], n: int, name: str) -> None:
    bad = [int(i) for i in idx if not 0 <= int(i) < n]
    if bad:
        raise ValueError(f"{name} out of range 0..{n - 1}: {bad}")


def _dofs(idx: IndexLike, n: int, name: str) -> np.ndarray:
    """0-based DOF indices (all when ``None``), checked."""
    arr = np.arange(n) if idx is None else np.atleast_1d(np.asarray(idx, dtype=int)).ravel()
    _check_dofs(arr, n, name)
    return arr


def _check_quantity(quantity: str) -> None:
    if quantity not in QUANTITIES:
        raise ValueError(f"quantity must be one of {QUANTITIES}, got {quantity!r}")


def _quantity_factor(omega: np.ndarray, quantity: str) -> np.ndarray:
    """``(j w)^p`` that turns receptance into the given quantity."""
    _check_quantity(quantity)
    return quantity_factor(omega, quantity_power(quantity))


def frf(
    system: MechanicalSystem,
    frequency_hz: np.ndarray,
    outputs: IndexLike = None,
    inputs: IndexLike = None,
    quantity: str = "displacement",
) -> np.ndarray:
    """Exact frequency response functions by a direct solve at every line.

    Parameters
    ----------
    system : MechanicalSystem
    frequency_hz : array, shape (n_freq,)
        Lines in Hz.
    outputs, inputs : int or sequence of int, optional
        0-based response and force DOFs (default: all).
    quantity : {"displacement", "velocity", "acceleration"}
        Receptance ``H``, mobility ``j w H`` or accelerance ``-w^2 H``.

    Returns
    -------
    ndarray, shape (n_freq, n_outputs, n_inputs), complex
        ``H[k, i, j]`` = rows ``outputs``, columns ``inputs`` of
        ``(K - w_k^2 M + j w_k C)^-1``, times the quantity's factor.
    """
    n = system.n_dof
    out, inp = _dofs(outputs, n, "output DOF"), _dofs(inputs, n, "input DOF")
    omega = 2.0 * np.pi * np.asarray(frequency_hz, dtype=float).reshape(-1)
    factor = _quantity_factor(omega, quantity)
    rhs = np.zeros((n, inp.size))
    rhs[inp, np.arange(inp.size)] = 1.0
    H = np.empty((omega.size, out.size, inp.size), dtype=complex)
    step = max(1, _CHUNK_BYTES // (16 * n * n))
    for start in range(0, omega.size, step):
        w = omega[start:start + step, None, None]
        Z = np.empty((w.shape[0], n, n), dtype=complex)
        Z.real[...] = system.K - w**2 * system.M
        Z.imag[...] = w * system.C
        X = np.linalg.solve(Z, np.broadcast_to(rhs, (w.shape[0], n, inp.size)))
        H[start:start + step] = X[:, out, :]
    return H * factor[:, None, None]


def state_space(
    system: MechanicalSystem,
    outputs: IndexLike = None,
    inputs: IndexLike = None,
    quantity: str = "displacement",
) -> StateSpace:
    """A continuous-time model whose transfer function ``C (sI - A)^-1 B + D`` is :func:`frf`.

    The state is ``[q; q']``. Displacement and velocity outputs have ``D = 0``;
    acceleration ``q'' = M^-1 (f - K q - C q')`` has ``D = M^-1`` at outputs x inputs.
    """
    _check_quantity(quantity)
    n = system.n_dof
    out, inp = _dofs(outputs, n, "output DOF"), _dofs(inputs, n, "input DOF")
    Minv_K = np.linalg.solve(system.M, system.K)
    Minv_C = np.linalg.solve(system.M, system.C)
    Minv_B = np.linalg.solve(system.M, np.eye(n)[:, inp])
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Minv_K, -Minv_C]])
    B = np.vstack([np.zeros((n, inp.size)), Minv_B])
    D = np.zeros((out.size, inp.size))
    if quantity == "displacement":
        C = np.hstack([np.eye(n)[out], np.zeros((out.size, n))])
    elif quantity == "velocity":
        C = np.hstack([np.zeros((out.size, n)), np.eye(n)[out]])
    else:
        C = A[n:][out]
        D = Minv_B[out]
    return StateSpace(A, B, C, D)


def exact_modes(
    system: MechanicalSystem, outputs: IndexLike = None, inputs: IndexLike = None
) -> Modes:
    """Exact modes from the first-order (state-space) eigenproblem.

    Exact for any viscous damping, proportional or not. Real (overdamped or rigid-body)
    poles are not modes and are left out.

    Parameters
    ----------
    system : MechanicalSystem
    outputs : int or sequence of int, optional
        0-based sensor DOFs for the shapes (default: all).
    inputs : int or sequence of int, optional
        0-based force DOFs; when given, the receptance residues are computed too.

    Returns
    -------
    Modes
        Sorted by natural frequency.
    """
    n = system.n_dof
    out = _dofs(outputs, n, "output DOF")
    A, B, C, _ = state_space(system, out, [] if inputs is None else inputs)
    lam, V = np.linalg.eig(A)
    scale = np.maximum(np.abs(lam), 1.0)
    keep = np.flatnonzero(lam.imag > 1e-10 * scale)
    keep = keep[np.argsort(np.abs(lam[keep]), kind="stable")]
    shapes = unit_max_shapes(C @ V[:, keep])
    residues = None
    if inputs is not None:
        L = np.linalg.solve(V, B)[keep]  # modal participation, (n_modes, n_inputs)
        residues = (C @ V[:, keep]).T[:, :, None] * L[:, None, :]
    return Modes.from_poles(lam[keep], shapes, residues)


def modal_frf(
    modes: Modes, frequency_hz: np.ndarray, quantity: str = "displacement"
) -> np.ndarray:
    """FRF synthesised from poles and residues (the modal sum).

    Returns
    -------
    ndarray, shape (n_freq, n_outputs, n_inputs), complex
    """
    if modes.residues is None:
        raise ValueError("the modes have no residues (give the inputs to exact_modes)")
    s = 2j * np.pi * np.asarray(frequency_hz, dtype=float).reshape(-1)
    lam = modes.poles
    H = np.einsum("kr,rij->kij", 1.0 / (s[:, None] - lam), modes.residues)
    H += np.einsum("kr,rij->kij", 1.0 / (s[:, None] - lam.conj()), modes.residues.conj())
    return H * _quantity_factor(s.imag, quantity)[:, None, None]


# --------------------------------------------------------------------------- noise


def complex_gaussian(
    shape: tuple[int, ...], std: float | np.ndarray, rng: RngLike = None
) -> np.ndarray:
    """Circular complex Gaussian noise with standard deviation ``std`` (broadcast to
    ``shape``): real and imaginary parts each have ``std / sqrt(2)``.
    """
    rng = np.random.default_rng(rng)
    z = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return z * (np.asarray(std, dtype=float) / np.sqrt(2.0))


def rms_over_lines(H: np.ndarray) -> np.ndarray:
    """RMS magnitude of each FRF entry over the lines (axis 0), kept as a length-1 axis."""
    H = np.asarray(H)
    return np.sqrt(np.mean(np.abs(H) ** 2, axis=0, keepdims=True))


def add_noise(
    H: np.ndarray, level: float, rng: RngLike = None, kind: str = "proportional"
) -> np.ndarray:
    """FRF plus complex Gaussian measurement noise.

    Parameters
    ----------
    H : ndarray, shape (n_freq, ...)
        Clean FRF (lines along axis 0).
    level : float
        Relative noise level (0.01 = 1 %).
    rng : numpy Generator, int seed or None
    kind : {"proportional", "additive"}
        ``"proportional"``: std ``level * |H[k]|`` per entry and line.
        ``"additive"``: std ``level * RMS_k |H[k]|`` of that entry, the same at every line.

    Returns
    -------
    ndarray
        A new array, ``H + noise``.
    """
    if kind not in NOISE_KINDS:
        raise ValueError(f"noise kind must be one of {NOISE_KINDS}, got {kind!r}")
    if not level >= 0:
        raise ValueError("noise level must be >= 0")
    H = np.asarray(H, dtype=complex)
    scale = np.abs(H) if kind == "proportional" else rms_over_lines(H)
    return H + complex_gaussian(H.shape, level * scale, rng)


# --------------------------------------------------------------------------- whole test


def frequency_lines(f_max: float, n_lines: int, f_min: float | None = None) -> np.ndarray:
    """Equidistant lines: ``f_min .. f_max`` inclusive, or, without ``f_min``,
    ``f_max * (1..n_lines) / n_lines`` (the 0 Hz line of a measured spectrum dropped).
    """
    if n_lines < 2:
        raise ValueError("need at least 2 lines")
    if f_min is None:
        return f_max * np.arange(1, n_lines + 1) / n_lines
    if not 0 <= f_min < f_max:
        raise ValueError("need 0 <= f_min < f_max")
    return np.linspace(f_min, f_max, n_lines)


def synthetic_attributes(system: MechanicalSystem, seed: int, noise: float) -> dict[str, Any]:
    """The file attributes every synthetic test carries: ``structure``, ``generator``,
    ``seed``, ``noise_level`` and ``damping`` (kind)."""
    return {
        "structure": str(system.meta.get("name", system.meta.get("kind", "system"))),
        "generator": "automodal simulate",
        "seed": int(seed),
        "noise_level": float(noise),
        "damping": str(system.meta.get("damping", {}).get("kind", "none")),
    }


def simulate_test(
    system: MechanicalSystem,
    outputs: IndexLike,
    inputs: IndexLike,
    frequency_hz: np.ndarray,
    quantity: str = "displacement",
    noise: float = 0.01,
    seed: int | None = None,
    noise_kind: str = "proportional",
    pure_noise: bool = False,
) -> tuple[FRFData, Modes]:
    """A synthetic test: the FRF of a known system with noise, and its exact modes.

    Parameters
    ----------
    system : MechanicalSystem
    outputs, inputs : int or sequence of int
        0-based sensor and force DOFs.
    frequency_hz : array
        Lines in Hz.
    quantity : {"displacement", "velocity", "acceleration"}
    noise : float
        Relative noise level (see :func:`add_noise`).
    seed : int, optional
        Seed of ``numpy.random.default_rng``; the same seed gives the same numbers. When
        ``None`` one is drawn, and in either case it is recorded in the attributes.
    noise_kind : {"proportional", "additive"}
    pure_noise : bool
        Replace the FRF by complex Gaussian noise with the RMS level of each clean entry and
        no structure at all; the returned modes are then empty.

    Returns
    -------
    data : FRFData
        Channel names ``dofN``, nodes ``N`` (1-based), direction ``+Z``, coordinates.
    modes : Modes
        Exact modes at the outputs, with residues for the inputs.
    """
    n = system.n_dof
    out, inp = _dofs(outputs, n, "output DOF"), _dofs(inputs, n, "input DOF")
    if seed is None:
        seed = int(np.random.SeedSequence().generate_state(1)[0])
    rng = np.random.default_rng(seed)
    f = np.asarray(frequency_hz, dtype=float).reshape(-1)
    H = frf(system, f, out, inp, quantity)
    if pure_noise:
        H = complex_gaussian(H.shape, rms_over_lines(H), rng)
        modes = Modes.empty(out.size, inp.size)
    else:
        H = add_noise(H, noise, rng, noise_kind)
        modes = exact_modes(system, out, inp)
    attributes = {
        **synthetic_attributes(system, seed, noise),
        "noise_kind": noise_kind,
        "pure_noise": int(bool(pure_noise)),
    }
    data = FRFData(
        frequency=f,
        frf=H,
        quantity=quantity,
        output_names=[f"dof{i + 1}" for i in out],
        input_names=[f"dof{j + 1}" for j in inp],
        output_nodes=out + 1,
        input_nodes=inp + 1,
        output_directions=["+Z"] * out.size,
        input_directions=["+Z"] * inp.size,
        output_xyz=None if system.xyz is None else system.xyz[out],
        attributes=attributes,
    )
    return data, modes
