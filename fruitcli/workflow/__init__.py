"""The workflow: which stages a scene needs (`planner`), the stage table (`stages`), the
types both share (`stage_types`), the reduced model built on demand through the planner
(`reduced_model`) and the demo's report (`report`).

May import every other package of `fruitcli` except `fruitcli.cli`.
"""
