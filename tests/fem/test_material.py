import numpy as np
import pytest

from signorini.errors import InputError
from signorini.fem.material import IsotropicElastic


def test_conversions_roundtrip():
    m = IsotropicElastic(0.25, 0.5, 1.0)
    # a few flops each: measured 1.1e-16 relative at most
    assert np.allclose([m.young, m.poisson], [7 / 6, 1 / 6], rtol=1e-14, atol=0)
    m2 = IsotropicElastic.from_young(m.young, m.poisson, 1.0)
    assert np.allclose([m2.lam, m2.mu], [0.25, 0.5], rtol=1e-14, atol=0)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        (dict(lam=1, mu=1, rho=0), "rho"),
        (dict(lam=1, mu=-1, rho=1), "mu"),
        (dict(lam=-1, mu=1, rho=1), "3 lam \\+ 2 mu"),
    ],
)
def test_validation(kwargs, field):
    with pytest.raises(InputError, match=field):
        IsotropicElastic(**kwargs)


def test_young_validation():
    with pytest.raises(InputError, match="nu"):
        IsotropicElastic.from_young(1.0, 0.5)
    with pytest.raises(InputError, match="E"):
        IsotropicElastic.from_young(-1.0, 0.2)


def test_von_mises_uniaxial():
    m = IsotropicElastic.from_young(2.0, 0.0)
    eps = np.zeros((3, 3))
    eps[0, 0] = 0.1
    assert np.isclose(m.von_mises(eps), 0.2, rtol=1e-14, atol=0)  # uniaxial stress E eps with nu = 0: 1.4e-16
