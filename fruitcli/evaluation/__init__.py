"""Evaluation (paper Sec. V-B, Table I): measured points against ground truth, registered
as the paper's data are (`register`), error statistics (`metrics`), tables (`report`)
and top and side views (`plots`). Units: mm and % of a reference length.

May import: `fruitcli.errors`, `fruitcli.fsutil`, `fruitcli.tables`.
"""
