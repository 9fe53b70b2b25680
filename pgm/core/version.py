"""The toolkit's version (``pgm.__version__``), at the bottom layer so that every module may
record it (``run.json``: :func:`pgm.io.outputs.provenance`)."""

__version__ = "0.1.0"
