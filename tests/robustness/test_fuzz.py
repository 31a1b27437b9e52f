"""A short fuzzing run of every reader and parser (`make fuzz` runs them long): a correct
result, or the project's own error in one line naming the input."""

import pytest
from hypothesis import HealthCheck, given, settings

from tests.robustness.fuzz_targets import TARGETS

SHORT = settings(
    max_examples=40, deadline=None, database=None, suppress_health_check=list(HealthCheck)
)


@pytest.mark.parametrize("name", list(TARGETS))
def test_reader_gives_a_result_or_one_clean_line(name):
    strategy, check = TARGETS[name]

    @SHORT
    @given(strategy())
    def prop(value):
        check(value)

    prop()
