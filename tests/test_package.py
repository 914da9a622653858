"""The package's public names: each the object its module defines, loaded on first use, so that
`import sac_jax` alone imports no JAX; an unknown name fails as Python's own would."""

import importlib
import subprocess
import sys

import pytest

import sac_jax


def test_import_sac_jax_loads_no_jax_until_a_name_is_used():
    probe = ("import sys, sac_jax; before = 'jax' in sys.modules; sac_jax.make_train; "
             "print(before, 'jax' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                         check=True).stdout
    assert out.split() == ["False", "True"]


def test_every_public_name_is_the_object_its_module_defines():
    assert sac_jax.__all__ == sorted(sac_jax._HOMES)
    for name, home in sac_jax._HOMES.items():
        expected = importlib.import_module(f"sac_jax.{home or name}")
        assert getattr(sac_jax, name) is (expected if home is None else getattr(expected, name))
    assert set(sac_jax.__all__) <= set(dir(sac_jax))
    from sac_jax import SACConfig, losses, make_train  # noqa: F401  (from-imports resolve too)


def test_an_unknown_name_fails_as_pythons_own_would():
    with pytest.raises(AttributeError, match=r"^module 'sac_jax' has no attribute 'nope'$"):
        sac_jax.nope
    with pytest.raises(ImportError, match="cannot import name 'nope' from 'sac_jax'"):
        from sac_jax import nope  # noqa: F401
