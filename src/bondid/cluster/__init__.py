"""The Dask engine that spreads work over processes or machines: :mod:`.client` opens a local
cluster of worker processes or connects to the user's scheduler; :mod:`.worker_stderr`
relays what the workers print. ``bondid.fleet`` (one job per machine) and
``bondid.diagnose`` (one refit per candidate effect) both run on it.
"""
