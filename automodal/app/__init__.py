"""The application layer: one file's run, batches, monitoring against a baseline, figures.

Apart from the numerical core (:mod:`automodal.core`, :mod:`automodal.pipeline`) and the
file formats (:mod:`automodal.io`); the command line (:mod:`automodal.cli`) only parses
options and calls these modules. Nothing is imported here, so that importing a submodule
stays cheap.
"""
