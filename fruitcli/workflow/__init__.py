"""The workflow: which stages a scene needs (`planner`), the stage table (`stages`), its
entries by concept (`geometry_stages`, `fem_stages`, `sensing_stages`), where stages find
their inputs (`stage_paths`), the types planner and stages share (`stage_types`), the
reduced model built on demand through the planner (`reduced_model`) and the demo's
report (`report`).

May import every other package of `fruitcli` except `fruitcli.cli`.
"""
