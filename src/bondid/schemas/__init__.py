"""JSON Schemas of the result files (``fit.json``, ``sensitivity.json``, ``diagnosis.json``,
``modes.json``, ``fleet.json``), shipped as package data: ``<name>.schema.json`` here, read
with ``importlib.resources.files("bondid.schemas")``. They allow keys a later version adds
(extend, never break); the docs' reference pages are generated from them."""
