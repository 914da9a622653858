"""sac_jax/cli.py: every kind of bad command line tyro reports becomes one line naming the flag
and the value (UsageError), and good input parses as tyro parses it."""

import dataclasses
from typing import Literal, Optional, Tuple

import pytest
import tyro

from sac_jax.cli import UsageError, parse, positive


@dataclasses.dataclass(frozen=True)
class Args:
    """A command line with one argument of each kind."""

    run: tyro.conf.Positional[str]
    """A required positional."""
    count: int = 1
    which: Literal["a", "b"] = "a"
    sizes: Tuple[int, ...] = (2, 2)
    flag: bool = False
    scale: Optional[float] = None

    def __post_init__(self):
        positive("count", self.count)


@pytest.mark.parametrize("argv, message", [
    (["r", "--count", "x"], "--count: invalid literal for int() with base 10: 'x'"),
    (["r", "--count", "0"], "--count=0: must be a positive integer"),
    (["r", "--which", "c"], "--which='c': must be one of ['a', 'b']"),
    (["r", "--count"], "--count: expected a value"),
    (["r", "--sizes", "2", "y"], "--sizes: Could not find valid parse for arguments: ['2', 'y']"),
    (["r", "--nope", "3"], "unrecognized arguments: --nope 3 (see --help)"),
    (["r", "--flag", "yes"], "unrecognized arguments: yes (see --help)"),
    ([], "missing run (see --help)"),
])
def test_each_kind_of_bad_input_is_one_line(argv, message):
    with pytest.raises(UsageError) as error:
        parse(Args, argv)
    assert str(error.value) == message and "\n" not in str(error.value)


def test_good_input_and_defaults():
    assert parse(Args, ["r", "--count", "3", "--which", "b", "--sizes", "4", "5", "--flag",
                        "--scale", "None"]) == Args("r", 3, "b", (4, 5), True, None)
    assert parse(Args, ["r"], default=Args("x", count=7)) == Args("r", count=7)


def test_positive_rejects_bools_and_non_positive():
    for value in (0, -1, True, 1.5):
        with pytest.raises(ValueError, match="must be a positive integer"):
            positive("n", value)
    positive("n", 1)
