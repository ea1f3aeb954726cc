"""``automodal simulate``: write a synthetic test of a known system."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import click
import numpy as np
from click.core import ParameterSource

from automodal.cli._common import (
    FiniteFloatRange,
    check_hdf5_suffix,
    check_output_folder,
    checked_test_date,
    debug_option,
    exit_on_error,
    test_date_option,
)
from automodal.errors import InputError
from automodal.io.limits import MAX_VALUES
from automodal.quantities import QUANTITIES

if TYPE_CHECKING:  # annotations only: --help must not load the numerical core
    from automodal.core.simulate import MechanicalSystem


def parse_dofs(text: str, n_dof: int, option: str) -> list[int]:
    """1-based DOF list ``"1,3,5-8"`` or ``"all"`` -> 0-based indices, in the given order.

    Raises
    ------
    click.BadParameter
        A number out of ``1..n_dof``, a repeat, or text that is not a list of numbers.
    """
    text = text.strip().lower()
    if text == "all":
        return list(range(n_dof))
    dofs: list[int] = []
    try:
        for part in filter(None, (p.strip() for p in text.split(","))):
            lo, _, hi = part.partition("-")
            first, last = int(lo), int(hi or lo)
            if first > last:
                raise ValueError(part)
            dofs.extend(range(first, last + 1))
    except ValueError:
        raise click.BadParameter(f"{text!r} is not a list of DOF numbers like 1,3,5-8 or 'all'",
                                 param_hint=option) from None
    if not dofs:
        raise click.BadParameter("no DOF given", param_hint=option)
    bad = sorted({d for d in dofs if not 1 <= d <= n_dof})
    if bad:
        raise click.BadParameter(f"DOF {bad[0]} is outside 1..{n_dof}", param_hint=option)
    if len(set(dofs)) != len(dofs):
        raise click.BadParameter("a DOF is listed twice", param_hint=option)
    return [d - 1 for d in dofs]


FRF_ONLY = ("lines", "fmin", "fmax", "noise_kind", "pure_noise")
"""Options of the FRF excitation only (the spectrum the file holds)."""

TIME_ONLY = ("sample_rate", "duration", "hits", "pulse_width")
"""Options of the time excitations only (how the records are sampled)."""

HITS_ONLY = ("hits", "pulse_width")
"""Options of the hammer excitation only (random and ambient forces have no hits)."""


def _given(names: tuple[str, ...]) -> list[str]:
    """The options among ``names`` that the command line set (not left at their default)."""
    ctx = click.get_current_context()
    return [n for n in names
            if ctx.get_parameter_source(n) not in (ParameterSource.DEFAULT, None)]


def _option(name: str) -> str:
    return "--" + name.replace("_", "-")


def modes_path(output: Path) -> Path:
    """``<dir>/<stem>.modes.json`` beside the FRF or time file."""
    return output.with_name(output.stem + ".modes.json")


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}" + ("" if n == 1 else "s")


def _range(values: np.ndarray, fmt: str) -> str:
    if values.size == 0:
        return "-"
    lo, hi = format(values.min(), fmt), format(values.max(), fmt)
    return lo if lo == hi else f"[{lo}, {hi}]"


@click.command(
    "simulate",
    context_settings={"help_option_names": ["-h", "--help"]},
    epilog="""\b
Examples:
  automodal simulate chain6.h5 --dof 6 --inputs 6 --seed 1
  automodal simulate plate.h5 --system grid --grid 3 4 --outputs 1,3,5-8 \\
      --inputs 1,12 --quantity acceleration --damping nonproportional
  automodal simulate noise.h5 --pure-noise --seed 7
  automodal simulate hammer.h5 --excitation hits --hits 8 --quantity acceleration
  automodal simulate shaker.h5 --excitation random --noise 0.05 --seed 3
  automodal simulate ambient.h5 --excitation ambient --duration 3600""",
)
@click.argument("output", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--system", "system_kind", type=click.Choice(["chain", "grid"]), default="chain",
              show_default=True,
              help="Spring-mass chain grounded at DOF 1, or 2-D grid of masses.")
@click.option("--dof", type=click.IntRange(min=1), default=6, show_default=True,
              help="Chain: number of masses.")
@click.option("--grid", "grid_size", type=click.IntRange(min=1), nargs=2, default=(3, 4),
              show_default=True, metavar="NX NY", help="Grid: masses along x and y.")
@click.option("--symmetric", is_flag=True,
              help="Grid: equal x and y springs (repeated or close modes).")
@click.option("--outputs", default="all", show_default=True,
              help="Sensor DOFs, 1-based: '1,3,5-8' or 'all'.")
@click.option("--inputs", default=None, help="Force DOFs, 1-based.  [default: the last DOF]")
@click.option("--quantity", type=click.Choice(QUANTITIES), default="displacement",
              show_default=True, help="Response measured: receptance, mobility or accelerance.")
@click.option("--damping", type=click.Choice(["rayleigh", "nonproportional"]), default="rayleigh",
              show_default=True,
              help="Rayleigh (real modes) or Rayleigh plus discrete dashpots (complex modes).")
@click.option("--zeta", type=FiniteFloatRange(min=0, max=0.5), default=0.01, show_default=True,
              help="Damping level: Rayleigh ratio at the lowest and highest mode "
              "(nonproportional: half that, plus dashpots adding up to it).")
@click.option("--noise", type=FiniteFloatRange(min=0), default=0.01, show_default=True,
              help="Relative noise level (0.01 = 1 %).")
@click.option("--noise-kind", type=click.Choice(["proportional", "additive"]),
              default="proportional", show_default=True,
              help="Noise std relative to |H| at each line, or to the RMS of each FRF.")
@click.option("--excitation", type=click.Choice(["frf", "hits", "random", "ambient"]),
              default="frf", show_default=True,
              help="frf: FRFs with noise. hits: hammer hits, forces and responses in time. "
              "random: white random forces at --inputs, measured. ambient: white random "
              "forces at --inputs (default all DOFs), outputs only.")
@click.option("--sample-rate", type=FiniteFloatRange(min=0, min_open=True), default=None,
              help="Time excitations: Hz.  [default: 3.2 x the highest natural frequency, "
              "rounded up]")
@click.option("--duration", type=FiniteFloatRange(min=0, min_open=True), default=None,
              help="Time excitations: record length in s.  [default: from the slowest "
              "mode's decay time; see docs/cli.md]")
@click.option("--hits", type=click.IntRange(min=1), default=5, show_default=True,
              help="Hits: number of hammer hits.")
@click.option("--pulse-width", type=FiniteFloatRange(min=0, min_open=True), default=None,
              help="Hits: width of the half-sine pulse in s.  [default: its spectrum half "
              "down at sample-rate / 2.56]")
@click.option("--lines", type=click.IntRange(min=2), default=1000, show_default=True,
              help="Number of frequency lines.")
@click.option("--fmin", type=FiniteFloatRange(min=0), default=None,
              help="Lowest line in Hz.  [default: fmax / lines, no 0 Hz line]")
@click.option("--fmax", type=FiniteFloatRange(min=0, min_open=True), default=None,
              help="Highest line in Hz.  [default: 1.25 x the highest natural frequency]")
@click.option("--pure-noise", is_flag=True,
              help="Write complex Gaussian noise with no structure (a test with no mode).")
@click.option("--seed", type=click.IntRange(min=0, max=2**63 - 1), default=None,
              help="Random seed; the one used is stored in both files.  [default: random]")
@test_date_option
@click.option("--quiet", "-q", is_flag=True, help="Print nothing on success.")
@debug_option
def simulate(output: Path, system_kind: str, dof: int, grid_size: tuple[int, int],
             symmetric: bool, outputs: str, inputs: str | None, quantity: str, damping: str,
             zeta: float, noise: float, noise_kind: str, lines: int, fmin: float | None,
             excitation: str, sample_rate: float | None, duration: float | None, hits: int,
             pulse_width: float | None, fmax: float | None, pure_noise: bool,
             seed: int | None, test_date: str | None, quiet: bool, debug: bool) -> None:
    """Write a synthetic test of a known system to OUTPUT.h5, with its exact modes.

    With --excitation frf (the default) the FRF file (docs/frf-file.md) gets the chosen
    responses per unit force with complex Gaussian noise. With hits, random or ambient it
    gets time records in its /time group instead: responses (and measured forces, except
    ambient) simulated exactly, with white noise of --noise times each channel's RMS.
    <OUTPUT stem>.modes.json beside it gets the exact modes at the sensors (frequency,
    damping ratio, shapes, residues) and every setting used.
    """
    # imported here so that `automodal simulate --help` does not load scipy and h5py
    from automodal.core import simulate as sim
    from automodal.io.frf_file import write_frf
    from automodal.io.modes_file import write_modes_json

    with exit_on_error(debug):
        check_hdf5_suffix(output, "FRF file")
        check_output_folder(output, "FRF file")
        check_output_folder(modes_path(output), "file of exact modes")
        when = None if test_date is None else checked_test_date(test_date)
        n_dof = dof if system_kind == "chain" else grid_size[0] * grid_size[1]
        if n_dof > MAX_DOF:
            raise InputError(f"{n_dof} DOFs: at most {MAX_DOF} are simulated (the exact modes"
                             " of a larger system take minutes and gigabytes)")
        if system_kind == "chain":
            system = sim.chain(dof)
        else:
            system = sim.grid(*grid_size, symmetric=symmetric)
        n = system.n_dof
        out = parse_dofs(outputs, n, "--outputs")
        system = sim.damp(system, damping, zeta)
        if excitation != "frf":
            wrong = _given(FRF_ONLY)
            if wrong:
                raise click.UsageError(f"{_option(wrong[0])} applies to --excitation frf only")
            wrong = [] if excitation == "hits" else _given(HITS_ONLY)
            if wrong:
                raise click.UsageError(f"{_option(wrong[0])} applies to --excitation hits only")
            _simulate_time(output, system, out, inputs, excitation, quantity, noise, seed,
                           sample_rate, duration, hits, pulse_width, when, quiet)
            return
        wrong = _given(TIME_ONLY)
        if wrong:
            raise click.UsageError(f"{_option(wrong[0])} applies to the time excitations "
                                   "only (--excitation hits, random or ambient)")
        inp = parse_dofs(str(n) if inputs is None else inputs, n, "--inputs")
        f_nat = sim.natural_frequencies_hz(system)
        f_top = 1.25 * f_nat.max() if fmax is None else fmax
        if fmin is not None and fmin >= f_top:
            raise click.BadParameter(f"{fmin} Hz is not below fmax = {f_top:.6g} Hz",
                                     param_hint="--fmin")
        n_values = lines * len(out) * len(inp)
        if n_values > MAX_VALUES:
            raise InputError(f"{lines} lines of {len(out)} x {len(inp)} FRFs are {n_values}"
                             f" values, more than the {MAX_VALUES} automodal reads back: ask"
                             " for fewer lines or channels")
        freq = sim.frequency_lines(f_top, lines, fmin)
        data, modes = sim.simulate_test(system, out, inp, freq, quantity, noise, seed,
                                        noise_kind, pure_noise)
        seed_used = _dated(data.attributes, when)
        mpath = modes_path(output)
        settings = _settings(
            {"frf_file": output.name}, system, out, inp, quantity, noise, seed_used,
            noise_kind=noise_kind, pure_noise=pure_noise, lines=lines,
            band_hz=[float(freq[0]), float(freq[-1])],
        )
        write_frf(output, data)
        write_modes_json(mpath, modes, settings)

        if not quiet:
            in_band = (modes.frequency_hz >= freq[0]) & (modes.frequency_hz <= freq[-1])
            what = "pure noise" if pure_noise else f"noise {100 * noise:g} % {noise_kind}"
            click.echo(
                f"{output}: {system.meta['name']}, {_count(len(out), 'output')} x "
                f"{_count(len(inp), 'input')}, "
                f"{quantity}, {lines} lines [{freq[0]:.4g}, {freq[-1]:.4g}] Hz, {what}, "
                f"seed {seed_used}; {mpath.name}: {modes.n_modes} modes "
                f"({in_band.sum()} in band, {_range(modes.frequency_hz, '.4g')} Hz, "
                f"zeta {_range(100 * modes.damping_ratio, '.2f')} %)"
            )


MAX_DOF = 500
"""Most DOFs ``simulate`` builds: its exact modes come from dense eigenproblems, whose cost
grows as the cube of the DOFs (a 500-DOF chain took 7 s, a 2000-DOF one 175 s, and a
100 000-DOF chain asked for 74 GiB)."""


def _dated(attributes: dict[str, Any], when: str | None) -> int:
    """The seed a simulation used (from its file attributes), after dating the file."""
    if when is not None:
        attributes["test_date"] = when
    return int(attributes["seed"])


def _settings(head: dict[str, Any], system: MechanicalSystem, out: list[int], inp: list[int],
              quantity: str, noise: float, seed: int, **rest: Any) -> dict[str, Any]:
    """The settings stored beside a simulated test: ``head`` (the file written), the system,
    the 1-based DOFs, quantity, noise and seed, then what is particular to the kind (``rest``,
    in its order before the seed)."""
    return {"command": "automodal simulate", **head, "system": system.meta,
            "outputs": [i + 1 for i in out], "inputs": [j + 1 for j in inp],
            "quantity": quantity, "noise": noise, **rest, "seed": seed}


def _simulate_time(output: Path, system: MechanicalSystem, out: list[int], inputs: str | None,
                   excitation: str, quantity: str, noise: float, seed: int | None,
                   sample_rate: float | None, duration: float | None, hits: int,
                   pulse_width: float | None, when: str | None, quiet: bool) -> None:
    """The time excitations: write the time file and the exact modes beside it."""
    from automodal.core import simulate_time as sim_time
    from automodal.io.modes_file import write_modes_json
    from automodal.io.time_file import write_time

    n = system.n_dof
    default_inputs = "all" if excitation == "ambient" else str(n)
    inp = parse_dofs(default_inputs if inputs is None else inputs, n, "--inputs")
    if excitation == "hits" and len(inp) != 1:
        raise click.BadParameter("a hammer test hits one DOF: give one", param_hint="--inputs")
    if not system.meta["damping"]["zeta"] > 0:
        raise click.BadParameter("time records need damping (> 0): an undamped mode never "
                                 "dies out", param_hint="--zeta")
    try:
        series, modes, plan = sim_time.simulate_time_test(
            system, out, inp, excitation, quantity, noise, seed, sample_rate, duration,
            hits, pulse_width, max_values=MAX_VALUES)
    except ValueError as exc:  # the sampling asked for does not make a test
        raise click.UsageError(str(exc)) from None
    seed_used = _dated(series.attributes, when)
    mpath = modes_path(output)
    settings = _settings(
        {"time_file": output.name, "excitation": excitation}, system, out, inp, quantity,
        noise, seed_used, inputs_measured=excitation != "ambient",
        noise_kind="white, std relative to each channel's RMS",
        sample_rate_hz=plan.sample_rate, n_samples=plan.n_samples, duration_s=plan.duration,
        duration_rule=plan.rule, hold=series.attributes["hold"],
    )
    if excitation == "hits":
        settings.update(hits=plan.n_hits, pulse_width_s=plan.pulse_width,
                        hit_spacing_samples=plan.hit_spacing, first_hit_sample=plan.first_hit)
    write_time(output, series)
    write_modes_json(mpath, modes, settings)
    if not quiet:
        what = f"{plan.n_hits} hits" if excitation == "hits" else excitation
        band = plan.sample_rate / 2.56
        in_band = modes.frequency_hz <= band
        click.echo(
            f"{output}: {system.meta['name']}, {_count(len(out), 'output')}, {what} at "
            f"{_count(len(inp), 'DOF')}, {quantity}, {plan.duration:.6g} s at "
            f"{plan.sample_rate:.6g} Hz ({plan.n_samples} samples), noise "
            f"{100 * noise:g} %, seed {seed_used}; {mpath.name}: {modes.n_modes} modes "
            f"({in_band.sum()} below fs/2.56, {_range(modes.frequency_hz, '.4g')} Hz, "
            f"zeta {_range(100 * modes.damping_ratio, '.2f')} %)"
        )
