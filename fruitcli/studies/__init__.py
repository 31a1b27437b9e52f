"""Studies over many runs: error against run time (`runtime`), numerical stability on
stiff and extreme cases (`stability`), what the virtual bench depends on (`bench_study`),
and sweeps of scene keys (`sweep`, `sweep_run`, `sweep_report`) on local processes or a
Dask cluster (`executors`, `parallel`).

May import every package but `fruitcli.cli`.
"""
