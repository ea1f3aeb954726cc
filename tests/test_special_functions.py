"""The incomplete gamma function of a whole-number shape and the Student t quantile, against
scipy.special."""

from __future__ import annotations

import math

import pytest
from scipy.special import chdtri, gammainc, gammaincc, gammaincinv

from automodal.core.integer_gamma import gamma_p, gamma_p_inverse, gamma_q, gamma_q_inverse

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
        # the upper tail's inverse, as the chi-square quantile of 2 k degrees of freedom
        assert 2.0 * gamma_q_inverse(k, p) == pytest.approx(chdtri(2 * k, p), rel=1e-13)


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
    with pytest.raises(ValueError, match="probability"):
        gamma_q_inverse(4, bad)


# ------------------------------------------------------------------ Student's t quantile

@pytest.mark.parametrize("dof", [0.3, 1.0, 2.5, 4.7, 10.0, 29.5, 99.5, 1e3, 1e4, 1e5])
def test_the_t_quantile_agrees_with_scipy(dof):
    from scipy.special import stdtrit

    from automodal.core.student_t import t_quantile

    rel = 1e-13 if dof <= 1e4 else 1e-11
    for p in (1e-9, 1e-3, 0.025, 0.3, 0.6, 0.975, 0.999999):
        assert t_quantile(dof, p) == pytest.approx(stdtrit(dof, p), rel=rel)
    assert t_quantile(dof, 0.5) == 0.0


def test_the_t_quantile_of_one_degree_of_freedom_is_a_cauchy_quantile():
    from automodal.core.student_t import t_quantile

    for p in (0.01, 0.3, 0.500000001, 0.975):
        assert t_quantile(1.0, p) == pytest.approx(math.tan(math.pi * (p - 0.5)), rel=1e-13)


def test_the_incomplete_beta_agrees_with_scipy():
    from scipy.special import betainc

    from automodal.core.student_t import incomplete_beta

    for a, b in ((0.5, 0.5), (2.0, 0.5), (50.0, 0.5), (0.5, 300.0), (3.3, 7.1)):
        for x in (0.0, 1e-6, 0.1, 0.5, 0.9, 0.999999, 1.0):
            assert incomplete_beta(a, b, x) == pytest.approx(betainc(a, b, x), rel=1e-12,
                                                             abs=1e-300)
