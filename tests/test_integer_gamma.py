"""The incomplete gamma function of a whole-number shape, against scipy.special."""

from __future__ import annotations

import math

import pytest
from scipy.special import gammainc, gammaincc, gammaincinv

from automodal.core.integer_gamma import gamma_p, gamma_p_inverse, gamma_q

SHAPES = [*range(1, 41), 64, 100, 250]


@pytest.mark.parametrize("k", SHAPES)
def test_the_tails_agree_with_scipy_and_sum_to_one(k):
    for x in (1e-6, 0.1, 1.0, 0.5 * k, k - 0.5, float(k), k + 0.5, 1.5 * k, 3.0 * k + 10.0, 700.0):
        p, q = gamma_p(k, x), gamma_q(k, x)
        assert p + q == pytest.approx(1.0, abs=1e-15)
        # the smaller tail is summed term by term: relatively accurate even when tiny
        for ours, theirs in ((p, gammainc(k, x)), (q, gammaincc(k, x))):
            if theirs < 0.5:
                assert ours == pytest.approx(theirs, rel=1e-11, abs=1e-300)
            else:
                assert ours == pytest.approx(theirs, abs=2e-15)


@pytest.mark.parametrize("k", SHAPES)
def test_the_inverse_agrees_with_scipy(k):
    for p in (1e-12, 1e-3, 0.02, 0.3, 0.5, 0.9, 0.98, 0.999, 1.0 - 1e-10):
        x = gamma_p_inverse(k, p)
        assert x == pytest.approx(gammaincinv(k, p), rel=1e-13)
        assert gamma_p(k, x) == pytest.approx(p, rel=1e-12)


def test_the_chi_square_with_two_degrees_of_freedom_is_an_exponential():
    # P(1, x) = 1 - exp(-x): its inverse is -log(1 - p)
    for p in (0.01, 0.5, 0.98):
        assert gamma_p_inverse(1, p) == pytest.approx(-math.log1p(-p), rel=1e-15)
    assert gamma_p(3, 0.0) == 0.0 and gamma_q(3, 0.0) == 1.0


@pytest.mark.parametrize("bad", [0, -1, 2.5])
def test_a_shape_that_is_not_a_whole_number_is_refused(bad):
    with pytest.raises(ValueError, match="whole number"):
        gamma_p(bad, 1.0)


@pytest.mark.parametrize("bad", [0.0, 1.0, -0.1, math.nan])
def test_a_probability_outside_the_open_unit_interval_is_refused(bad):
    with pytest.raises(ValueError, match="probability"):
        gamma_p_inverse(4, bad)
