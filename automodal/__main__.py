"""``python -m automodal``: the same command line as the ``automodal`` script."""

from automodal.cli import main

if __name__ == "__main__":
    main(prog_name="automodal")
