"""The examples in the docstrings are checked: they must print what they say."""

import doctest
import importlib
import pkgutil

import numpy as np
import pytest

import moments_ref

MODULES = sorted(
    m.name for m in pkgutil.walk_packages(moments_ref.__path__, "moments_ref.")
    if not m.name.endswith("__main__")
)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name):
    mod = importlib.import_module(name)
    with np.printoptions(legacy=False):
        res = doctest.testmod(mod, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE, verbose=False)
    assert res.failed == 0, f"{res.failed} of {res.attempted} docstring examples of {name} failed"
