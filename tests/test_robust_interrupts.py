"""Ctrl-C is one line and exit 130 whatever was running, a compiled kernel included."""

import pytest


def test_a_kernel_interrupted_by_ctrl_c_is_one_line(monkeypatch, capsys, tmp_path):
    from fruitcli.cli.main import main
    from fruitcli.evaluation import report

    def kernel(*args, **kwargs):
        try:
            raise KeyboardInterrupt
        except KeyboardInterrupt:  # as numba's dispatcher reports a signal inside a kernel
            raise SystemError("<function> returned a result with an exception set") from None

    monkeypatch.setattr(report, "evaluate_pair", kernel)
    with pytest.raises(SystemExit) as done:
        main(["evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out",
              str(tmp_path / "o")])
    assert done.value.code == 130
    assert capsys.readouterr().err == "Interrupted.\n"


def test_other_errors_still_show_their_traceback(monkeypatch, tmp_path):
    from fruitcli.cli.main import main
    from fruitcli.evaluation import report

    def broken(*args, **kwargs):
        raise SystemError("a real bug")

    monkeypatch.setattr(report, "evaluate_pair", broken)
    with pytest.raises(SystemError, match="a real bug"):
        main(["evaluate", "--truth", "t.csv", "--measured", "m.csv", "--out",
              str(tmp_path / "o")])
