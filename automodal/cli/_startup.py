"""What the command line does before a command's first scientific import.

scipy 1.14 and later, with numpy 2, build scipy's array-API view of numpy at import by
enumerating everything numpy exports, and numpy exports its submodules by name. So every
``import scipy.linalg`` executes ``numpy.f2py`` (the Fortran wrapper generator, which also
imports ``charset_normalizer`` when that is installed) and ``numpy.testing`` (which imports
``unittest``). No command of automodal uses either. Measured on the 2-core development
machine (scipy 1.17.1, numpy 2.4.6), the imports of an ``identify`` run took 1.04 s with
them and 0.81 s without (``benchmarks/results_imports.md``): an eighth of a small file's
wall time.

:func:`defer_unused_numpy_modules` registers those two modules with the standard library's
:class:`importlib.util.LazyLoader`: the names exist, so scipy's enumeration finds them, and
a module's code runs on the first access to one of its attributes, so whatever needs it
still gets the real module. It is called by the command line only, never on
``import automodal``: a library must not change how another package's modules load in its
caller's process.
"""

from __future__ import annotations

import importlib.util
import sys

DEFERRED = ("numpy.f2py", "numpy.testing")
"""numpy's submodules that scipy's import executes and no automodal command uses."""


def defer_unused_numpy_modules(names: tuple[str, ...] = DEFERRED) -> list[str]:
    """Make numpy submodules load on first use instead of on scipy's import.

    Parameters
    ----------
    names : tuple of str
        Dotted names of submodules of an importable package.

    Returns
    -------
    list of str
        The names made lazy. A module already imported, or one this numpy does not have, is
        left alone.

    Notes
    -----
    Only modules a run never touches are deferred: ``LazyLoader`` is not safe against two
    threads touching a module for the first time at once before CPython's fix of issue
    114763 (3.12.3 and 3.13; 3.10, 3.11 and early 3.12 have the race), and no command's
    worker threads touch either (``tests/test_cli_ux.py`` checks that an identify run, its
    threads included, leaves both unexecuted). Anything that goes wrong while deferring a
    module leaves it to load as usual: the deferral saves time, it must never stop a command.
    """
    deferred = []
    for name in names:
        if name in sys.modules:
            continue
        parent, _, child = name.rpartition(".")
        try:
            package = importlib.import_module(parent)
            spec = importlib.util.find_spec(name)
            if spec is None or spec.loader is None:
                continue
            loader = importlib.util.LazyLoader(spec.loader)  # TypeError: no exec_module
            spec.loader = loader
            module = importlib.util.module_from_spec(spec)
            sys.modules[name] = module
            loader.exec_module(module)
            # as an import does; without it, numpy's module __getattr__ would import the
            # name again and again
            setattr(package, child, module)
        except Exception:  # noqa: BLE001 - a deferral that fails is simply not made
            sys.modules.pop(name, None)
            continue
        deferred.append(name)
    return deferred
