"""Loads on the body: chamber pressure on curved cavity walls (`cavity`); jig springs
and gravity live in `fruitcli.fem.springs` and the models."""
