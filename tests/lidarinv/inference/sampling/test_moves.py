"""The ensemble-t move leaves the target invariant, on targets known in closed form; the
batched acceptance reproduces emcee's chains."""

import emcee
import numpy as np
import pytest

from lidarinv.inference.sampling import moves
from lidarinv.inference.sampling.moves import ChainStudentMove, EnsembleStudentMove


def _gamma_target(x):
    """Independent Gamma(shape 2, scale 1) per column: mean 2, variance 2, skewed."""
    with np.errstate(divide="ignore", invalid="ignore"):
        log_p = np.sum(np.log(x) - x, axis=1)
    return np.where(np.all(x > 0, axis=1), log_p, -np.inf)


@pytest.mark.parametrize("dof", [4.0, 50.0])
def test_samples_a_skewed_target_with_its_hastings_factor(dof):
    """The proposal is a symmetric t around the ensemble mean, the target skewed: a wrong
    Hastings factor pulls the samples off it (checked: without the factor the ensemble
    collapses, mean 1.2 and variance 0.14 at ν = 4)."""
    rng = np.random.default_rng(2)
    ndim, walkers = 3, 32
    sampler = emcee.EnsembleSampler(
        walkers, ndim, _gamma_target, vectorize=True, moves=EnsembleStudentMove(dof=dof)
    )
    sampler.random_state = np.random.RandomState(5).get_state()
    sampler.run_mcmc(rng.gamma(2.0, size=(walkers, ndim)), 3000, progress=False)
    x = sampler.get_chain(discard=300, flat=True)
    tau = np.max(emcee.autocorr.integrated_time(sampler.get_chain(discard=300), tol=0))
    assert tau < 10  # nearly independent draws
    np.testing.assert_allclose(x.mean(axis=0), 2.0, atol=0.08)
    np.testing.assert_allclose(x.var(axis=0), 2.0, rtol=0.1)
    skew = np.mean((x - x.mean(axis=0)) ** 3, axis=0) / x.var(axis=0) ** 1.5
    np.testing.assert_allclose(skew, np.sqrt(2.0), atol=0.25)  # Gamma(2): 2/√2


def test_fitted_chain_t_samples_a_skewed_target():
    """Once fitted, the chain-t proposal is one fixed t, here fitted to a poor guess
    (centred off the target's mean and too narrow): with its Hastings factor, and DE moves
    beside it as in the sampler, the chain still samples the target. (Alone, a t this
    narrow leaves walkers in the target's long tail for many steps: τ ≈ 50 against 10 for
    a t of the target's width.)"""
    rng = np.random.default_rng(3)
    ndim, walkers = 3, 32
    move = ChainStudentMove(dof=8.0)
    assert move.fit(rng.normal(1.5, 0.8, size=(500, ndim)))
    sampler = emcee.EnsembleSampler(
        walkers, ndim, _gamma_target, vectorize=True, moves=[(moves.DEMove(), 0.5), (move, 0.5)]
    )
    sampler.random_state = np.random.RandomState(6).get_state()
    sampler.run_mcmc(rng.gamma(2.0, size=(walkers, ndim)), 3000, progress=False)
    x = sampler.get_chain(discard=300, flat=True)
    np.testing.assert_allclose(x.mean(axis=0), 2.0, atol=0.1)
    np.testing.assert_allclose(x.var(axis=0), 2.0, rtol=0.12)
    skew = np.mean((x - x.mean(axis=0)) ** 3, axis=0) / x.var(axis=0) ** 1.5
    np.testing.assert_allclose(skew, np.sqrt(2.0), atol=0.3)


def test_fitted_chain_t_moves_every_walker_in_one_batch():
    """Its proposal no longer depends on the other walkers: one log-probability call a
    step, all walkers proposed (two calls, one half each, before the fit)."""
    calls = []

    def counting_target(x):
        calls.append(len(x))
        return _gamma_target(x)

    rng = np.random.default_rng(4)
    move = ChainStudentMove()
    sampler = emcee.EnsembleSampler(16, 3, counting_target, vectorize=True, moves=[move])
    start = rng.gamma(2.0, size=(16, 3))
    sampler.run_mcmc(start, 5, progress=False)
    assert calls[1:] == [8] * 10
    assert move.fit(rng.gamma(2.0, size=(500, 3)))
    calls.clear()
    sampler.run_mcmc(None, 5, progress=False)
    assert calls == [16] * 5


def test_chain_t_is_the_ensemble_t_until_fitted_and_refuses_a_singular_fit():
    current = np.random.default_rng(1).normal(size=(4, 3))
    others = [np.random.default_rng(2).normal(size=(8, 3))]
    proposals = [
        move.get_proposal(current, others, np.random.RandomState(0))
        for move in (ChainStudentMove(), EnsembleStudentMove())
    ]
    for chain_t, ensemble_t in zip(*proposals):
        np.testing.assert_array_equal(chain_t, ensemble_t)
    move = ChainStudentMove()
    flat = np.column_stack([np.arange(10.0), np.arange(10.0), np.ones(10)])  # rank 1
    assert not move.fit(flat)
    assert move.mean is None


def test_too_few_walkers_for_a_covariance_leave_them_in_place():
    move = EnsembleStudentMove()
    current = np.arange(12.0).reshape(4, 3)
    others = [np.ones((3, 3))]  # 3 walkers cannot span 3 dimensions
    proposal, log_factor = move.get_proposal(current, others, np.random.RandomState(0))
    np.testing.assert_array_equal(proposal, current)
    np.testing.assert_array_equal(log_factor, 0.0)
    with pytest.raises(ValueError, match="positive"):
        EnsembleStudentMove(dof=0.0)


@pytest.mark.parametrize("name", ["de", "de-snooker", "stretch", "walk", "kde"])
def test_batched_acceptance_gives_emcee_chain_exactly(name):
    """Same random stream, same order: the batched red-blue step makes the very chain of
    emcee's walker-by-walker loop, with the target's −inf region included."""
    ours = moves.MOVES[name]
    theirs = getattr(emcee.moves, ours.__name__)
    chains = []
    for move in (ours(), theirs()):
        sampler = emcee.EnsembleSampler(16, 3, _gamma_target, vectorize=True, moves=move)
        sampler.random_state = np.random.RandomState(9).get_state()
        start = np.random.default_rng(1).gamma(2.0, size=(16, 3))
        sampler.run_mcmc(start, 200, progress=False)
        chains.append((sampler.get_chain(), sampler.get_log_prob(), sampler.acceptance_fraction))
    for a, b in zip(*chains):
        np.testing.assert_array_equal(a, b)
    assert 0.05 < chains[0][2].mean() < 0.95
