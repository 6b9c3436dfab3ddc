"""The sampler harness on a posterior known in closed form (linear-Gaussian toy)."""

from dataclasses import replace

import emcee
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from forward.stand_params import StandParams
from lidarinv.examples import ShotRecipe, synthetic_shot
from lidarinv.inference import InversionSettings, build_problem
from lidarinv.inference.model.priors import Uniform
from lidarinv.inference.model.space import Parameter, ParameterSpace
from lidarinv.inference.model.stand import TOP_SDS
from lidarinv.inference.sampling import SamplerSettings, burn_in, find_map, run_sampler
from lidarinv.inference.sampling.ensemble import BatchedSampler, sample_in_chunks
from lidarinv.inference.sampling.importance import ImportanceSettings
from lidarinv.inference.sampling.moves import MOVES
from lidarinv.inference.sampling.sampler import may_converge


class LinearGaussianToy:
    """y = A·θ + ε, ε ~ N(0, σ²I), flat priors: posterior N(μ, Σ) in closed form.

    Called like the real log-posterior: unbounded coordinates in, (n, 1 + blobs) out.
    """

    def __init__(self, space, rng):
        self.space = space
        self.a = rng.normal(size=(30, space.ndim))
        self.a[:, 1] += 0.8 * self.a[:, 0]  # correlated parameters
        self.sigma = 0.5
        self.truth = np.array([1.0, -2.0, 0.5])
        self.y = self.a @ self.truth + self.sigma * rng.normal(size=30)
        precision = self.a.T @ self.a / self.sigma**2
        self.cov = np.linalg.inv(precision)
        self.mean = self.cov @ self.a.T @ self.y / self.sigma**2

    def __call__(self, u):
        x, log_jac = self.space.from_unbounded(u)
        r = self.y[None, :] - x @ self.a.T
        log_post = -0.5 * np.sum(r * r, axis=1) / self.sigma**2
        log_post += self.space.log_prior(x) + log_jac
        return np.column_stack([log_post, x.sum(axis=1)])


@pytest.fixture(scope="module", params=["importance", "chain"])
def toy_run(request):
    """The toy sampled to convergence: by default (the Gaussian passes the importance
    draws at their first try), and by the chain alone."""
    rng = np.random.default_rng(42)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    draws = ImportanceSettings().draws if request.param == "importance" else 0
    settings = SamplerSettings(
        n_walkers=16, max_steps=6000, check_every=250, importance=ImportanceSettings(draws)
    )
    return toy, run_sampler(toy, space, rng, settings)


def test_toy_posterior_matches_closed_form(toy_run):
    toy, run = toy_run
    assert run.converged, run.flags
    if run.importance is not None:  # it ended at the first try
        assert run.importance.step == ImportanceSettings().steps[0] == run.chain.shape[0]
    u, _, _ = run.draws()
    x, _ = toy.space.from_unbounded(u)
    n_eff = np.min(run.coordinate_ess())
    mcse = np.sqrt(np.diag(toy.cov) / n_eff)
    np.testing.assert_array_less(np.abs(x.mean(axis=0) - toy.mean), 5 * mcse)
    np.testing.assert_allclose(np.cov(x.T), toy.cov, rtol=0.25, atol=0.05 * np.max(toy.cov))


def test_tau_from_the_thinned_chain_is_the_full_chains():
    rng = np.random.default_rng(8)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    # DE moves alone give τ ≈ 12 on the toy (the ensemble-t move, τ ≈ 2, would not thin)
    de_only = (("de", 0.7), ("de-snooker", 0.1), ("stretch", 0.2))
    coarse = SamplerSettings(
        n_walkers=16, max_steps=3000, check_every=250, tau_resolution=3, moves=de_only,
        stop_rule="tau",
    )  # fmt: skip
    run = run_sampler(toy, space, rng, coarse)  # each check thins by about 4
    full = emcee.autocorr.integrated_time(run.chain[run.burn :], tol=0, quiet=True)
    assert np.min(run.tau) / 3 >= 3
    np.testing.assert_allclose(run.tau, full, rtol=0.1)


def test_blobs_follow_the_chain(toy_run):
    toy, run = toy_run
    x, _ = toy.space.from_unbounded(run.chain[-1])
    blobs = run.blobs.reshape(run.blobs.shape[0], run.blobs.shape[1], -1)
    np.testing.assert_allclose(blobs[-1, :, 0], x.sum(axis=1))


def test_batched_sampler_walks_the_chain_emcee_walks():
    rng = np.random.default_rng(11)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    start = 0.1 * rng.standard_normal((16, 3))
    chains = []
    for cls, extra in ((BatchedSampler, {}), (emcee.EnsembleSampler, {"blobs_dtype": float})):
        sampler = cls(16, 3, toy, vectorize=True, **extra)
        sampler.random_state = np.random.RandomState(4).get_state()
        sampler.run_mcmc(start, 200)
        chains.append((sampler.get_chain(), sampler.get_log_prob(), sampler.get_blobs()))
    for ours, emcees in zip(*chains):
        np.testing.assert_array_equal(ours, emcees)


def test_batched_sampler_refuses_a_nan_log_probability():
    nan_at_origin = lambda u: np.column_stack([np.where(u[:, 0] > 0, 0.0, np.nan), u[:, 0]])
    sampler = BatchedSampler(4, 1, nan_at_origin, vectorize=True)
    with pytest.raises(ValueError, match="returned NaN"):
        sampler.run_mcmc(np.linspace(-1.0, 1.0, 4)[:, None], 1)


def _stored_steps(backend) -> int:
    """Steps the backend's chain storage holds room for (taken or not)."""
    if isinstance(backend, emcee.backends.HDFBackend):
        with backend.open() as handle:
            return handle[backend.name]["chain"].shape[0]
    return len(backend.chain)


@pytest.mark.parametrize("hdf5", [False, True])
def test_chunked_steps_walk_the_chain_one_call_walks(tmp_path, hdf5):
    """Chunks of 30, 30, 60 and 20 steps, then 110, give the very chain, log-probabilities
    and blobs of one 250-step ``sample`` call, with the moves of a real run; the storage
    stays within twice the steps taken (one call allocates them all up front)."""
    rng = np.random.default_rng(11)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    start = 0.1 * rng.standard_normal((16, 3))
    runs = []
    for chunked in (False, True):
        backend = emcee.backends.HDFBackend(str(tmp_path / f"{chunked}.h5")) if hdf5 else None
        moves = [(MOVES[name](), weight) for name, weight in SamplerSettings().moves]
        sampler = BatchedSampler(16, 3, toy, vectorize=True, moves=moves, backend=backend)
        sampler.random_state = np.random.RandomState(4).get_state()
        if chunked:
            for _ in sample_in_chunks(sampler, start, 140, first=30):
                pass
            assert len(sampler.backend.get_chain()) == 140
            assert sampler.backend.shape == (16, 3)
            assert _stored_steps(sampler.backend) <= 2 * 140
            for _ in sample_in_chunks(sampler, sampler.get_last_sample(), 110, first=30):
                pass
        else:
            for _ in sampler.sample(start, iterations=250):
                pass
            assert _stored_steps(sampler.backend) == 250
        runs.append((sampler.get_chain(), sampler.get_log_prob(), sampler.get_blobs()))
    for chunked, whole in zip(*runs[::-1]):
        assert chunked.shape[0] == 250
        np.testing.assert_array_equal(chunked, whole)


@given(
    tau=st.floats(1.0, 500.0),
    spread=st.floats(0.1, 1.0),
    change=st.floats(0.9, 1.1),
    iteration=st.integers(10, 60_000),
    floor=st.sampled_from([0, 100, 200, 400, 800, 1600, 3200]),
)
def test_a_skipped_check_could_not_have_ended_the_run(tau, spread, change, iteration, floor):
    """Also after a chain-t fit at ``floor``, whose steps before are always discarded."""
    settings = SamplerSettings()
    previous = np.array([tau, spread * tau])
    new = previous * np.array([change, 1.0])
    stable = np.all(np.abs(new - previous) < settings.tau_tolerance * new)
    kept = iteration - burn_in(iteration, previous, settings.burn_taus, floor)
    assert kept <= iteration - floor
    if stable and np.all(kept > settings.tau_multiple * new):
        assert may_converge(iteration, previous, settings, floor)


def test_map_and_laplace_covariance_match_the_closed_form():
    rng = np.random.default_rng(3)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    estimate = find_map(lambda u: toy(u)[:, 0], space, rng, SamplerSettings(starts=2))
    x, _ = space.from_unbounded(estimate.u[None, :])
    np.testing.assert_allclose(x[0], toy.mean, atol=5e-3)
    # the Laplace covariance in u maps back to Σ through dx/du
    _, log_jac_each = zip(
        *(p.prior.from_unbounded(estimate.u[i]) for i, p in enumerate(space.free))
    )
    scale = np.exp(np.array(log_jac_each))
    np.testing.assert_allclose(estimate.covariance * np.outer(scale, scale), toy.cov, rtol=0.05)


def test_a_seed_reaches_an_optimum_the_prior_draws_miss():
    """A broad hill and, far from it, a narrow higher peak that no screened prior draw
    climbs: seeded near the peak (as a nested model's optimum is), the search ends on it;
    a seed row with a non-finite coordinate is left out."""
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(2))
    peak = np.array([15.0, -15.0])

    def log_prob(u):
        x, log_jac = space.from_unbounded(u)
        hill = -0.5 * np.sum((x / 4.0) ** 2, axis=1)
        spike = 10.0 - 0.5 * np.sum(((x - peak) / 0.05) ** 2, axis=1)
        return np.logaddexp(hill, spike) + log_jac

    settings = SamplerSettings(candidates=64, starts=2, polish=1)
    plain = find_map(log_prob, space, np.random.default_rng(1), settings)
    seed = space.to_unbounded(np.array([peak + 0.1, [np.nan, 0.0]]))
    seeded = find_map(log_prob, space, np.random.default_rng(1), settings, seeds=seed)
    at = lambda estimate: space.from_unbounded(estimate.u[None, :])[0][0]
    assert np.linalg.norm(at(plain) - peak) > 5.0
    np.testing.assert_allclose(at(seeded), peak, atol=0.01)


def test_a_polish_lost_outside_the_support_keeps_its_start(monkeypatch):
    """A polish that ends worse than it began (L-BFGS-B's line search lost where the
    posterior is −inf ends at the penalty) keeps the screened point: the search never
    returns worse than a point it screened."""
    from scipy.optimize import OptimizeResult

    from lidarinv.inference.sampling import start

    rng = np.random.default_rng(3)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    screen = start.minimize_in_lockstep

    def lost_polish(objective, starts, method, options):
        if options["maxiter"] == SamplerSettings().screen_iterations:
            return screen(objective, starts, method=method, options=options)
        lost = np.full(len(starts[0]), 30.0)
        return [OptimizeResult(x=lost, fun=start._PENALTY, success=False) for _ in starts]

    monkeypatch.setattr(start, "minimize_in_lockstep", lost_polish)
    estimate = find_map(lambda u: toy(u)[:, 0], space, rng, SamplerSettings(starts=2))
    x, _ = space.from_unbounded(estimate.u[None, :])
    assert np.all(np.isfinite(x)) and estimate.optima
    np.testing.assert_allclose(x[0], toy.mean, atol=0.5)  # the screened optimum, not lost


def test_short_run_is_flagged_not_converged():
    rng = np.random.default_rng(5)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    run = run_sampler(toy, space, rng, SamplerSettings(n_walkers=8, max_steps=60, check_every=30))
    assert not run.converged
    assert any("not converged" in flag for flag in run.flags)


def test_unknown_move_is_refused_by_name():
    rng = np.random.default_rng(5)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    with pytest.raises(ValueError, match=r"unknown move.*'hmc'"):
        run_sampler(toy, space, rng, SamplerSettings(moves=(("de", 0.5), ("hmc", 0.5))))


def test_resume_from_hdf5_backend(tmp_path):
    import emcee

    rng = np.random.default_rng(8)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    path = tmp_path / "chain.h5"
    first = run_sampler(
        toy,
        space,
        rng,
        SamplerSettings(n_walkers=8, max_steps=50, check_every=25),
        backend=emcee.backends.HDFBackend(str(path), name="shot_1"),
    )
    assert first.chain.shape[0] == 50
    again = run_sampler(
        toy,
        space,
        rng,
        SamplerSettings(n_walkers=8, max_steps=90, check_every=20),
        backend=emcee.backends.HDFBackend(str(path), name="shot_1"),
    )
    assert again.chain.shape[0] == 90
    np.testing.assert_array_equal(again.chain[:50], first.chain)


def test_chain_t_is_fitted_then_frozen_and_refitted_on_resuming(tmp_path):
    """Burn-in reaches at least the chain-t move's first fit, and a resumed run refits it
    from the same stored steps: the chain is the very one an uninterrupted run makes
    (with no refit it is not)."""
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, np.random.default_rng(8))
    moves = (("de", 0.5), ("chain-t", 0.5))

    def run(path, steps, seed):
        settings = SamplerSettings(
            n_walkers=8,
            max_steps=steps,
            check_every=1000,
            moves=moves,
            fit_steps=(20, 40),
            fit_fraction=1.0,  # refit at 40 within either cap (60 or 100 steps)
        )
        backend = emcee.backends.HDFBackend(str(path), name="shot_1")
        return run_sampler(toy, space, np.random.default_rng(seed), settings, backend=backend)

    whole = run(tmp_path / "whole.h5", 100, 1)
    run(tmp_path / "parts.h5", 60, 1)
    resumed = run(tmp_path / "parts.h5", 100, 2)
    np.testing.assert_array_equal(resumed.chain, whole.chain)
    assert whole.burn == resumed.burn == 100 // 3  # τ unknown: a third, past the fit at 20


def test_steps_between_chain_t_refits_are_kept(monkeypatch):
    """Burn-in is 5 τ, at least the first fit, not the steps before the last refit: between
    fits the proposal is fixed, so each stretch is an exact chain. The kept chain, a refit
    inside it, still has the closed form's mean."""
    from lidarinv.inference.sampling import sampler as sampler_module

    fitted, fit_moves = [], sampler_module.fit_moves

    def recording_fit(sampler, adaptive, step=None):
        fitted.append(sampler.iteration)
        return fit_moves(sampler, adaptive, step)

    monkeypatch.setattr(sampler_module, "fit_moves", recording_fit)
    rng = np.random.default_rng(5)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    settings = SamplerSettings(
        n_walkers=16,
        max_steps=4000,
        check_every=100,
        moves=(("de", 0.5), ("chain-t", 0.5)),
        fit_steps=(20, 60),  # τ is unknown at both (the first check is at 100): both made
        stop_rule="tau",  # its burn-in: 5 τ of every coordinate at the last check
    )
    run = run_sampler(toy, space, rng, settings)
    assert run.converged, run.flags
    assert fitted == [20, 60]
    assert run.burn == max(20, int(np.ceil(settings.burn_taus * np.max(run.tau))))
    assert run.burn < 60  # the stretch between the fits is kept
    x, _ = space.from_unbounded(run.chain[run.burn :].reshape(-1, 3))
    mcse = np.sqrt(np.diag(toy.cov) * np.max(run.tau) / x.shape[0])
    np.testing.assert_array_less(np.abs(x.mean(axis=0) - toy.mean), 5 * mcse)


def test_chain_sampled_in_other_coordinates_is_not_resumed(tmp_path):
    import emcee

    rng = np.random.default_rng(9)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    path = tmp_path / "chain.h5"
    settings = SamplerSettings(n_walkers=8, max_steps=60, check_every=30)

    def run(coordinates, steps):
        backend = emcee.backends.HDFBackend(str(path), name="shot_1")
        settings_now = SamplerSettings(n_walkers=8, max_steps=steps, check_every=30)
        return run_sampler(toy, space, rng, settings_now, backend=backend, coordinates=coordinates)

    run(space.signature(), settings.max_steps)
    assert run(space.signature(), 90).chain.shape[0] == 90  # same coordinates: resumed
    wider = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-30.0, 30.0)) for i in range(3))
    assert wider.signature() != space.signature()
    with pytest.raises(ValueError, match="other coordinates"):
        run(wider.signature(), 120)


def test_map_search_reaches_the_basin_of_a_dense_even_aged_stand():
    """Dense crowns over a narrow height spread: the best few of many prior draws lie in
    a wrong basin (a wide height spread with the misfit taken up by a larger noise σ),
    which 4 starts from the best of 512 draws did not leave on 5 of 6 tries. The screened
    multi-start search reaches at least the true parameters' log-posterior."""
    params = StandParams(
        density=1460.0,
        height_mean=18.8,
        height_sd=1.03,
        height_family="truncnorm",
        height_truncation=TOP_SDS,
        shape_mix={"cone": 0.69, "ellipsoid": 0.31},
        crown_length_ratio=0.68,
        favd=1.01,
        understory_height=0.56,
        understory_lai=0.36,
        canopy_reflectance=0.486,
        ground_reflectance=0.3,
    )
    recipe = ShotRecipe(params, gain=4660.0)
    obs = synthetic_shot(recipe, np.random.default_rng(17), explicit=False)
    problem = build_problem(obs, InversionSettings(discrepancy=0.0))
    space = problem.space
    log_prob = lambda u: problem.log_posterior(u)[:, 0]
    truth = log_prob(space.to_unbounded(np.array([[obs.truth[n] for n in space.names]])))[0]
    estimate = find_map(log_prob, space, np.random.default_rng(5), SamplerSettings())
    assert estimate.log_prob >= truth - 1.0


class TwoModeToy:
    """Two well-separated Gaussian modes holding 70 % and 30 % of the mass."""

    def __init__(self, space):
        self.space = space
        self.centres = np.array([[-8.0, -8.0], [8.0, 8.0]])
        self.log_weights = np.log([0.7, 0.3])

    def __call__(self, u):
        x, log_jac = self.space.from_unbounded(u)
        d2 = np.sum((x[:, None, :] - self.centres[None]) ** 2, axis=2) / 0.3**2
        log_post = np.logaddexp(*(self.log_weights - 0.5 * d2).T)
        log_post += self.space.log_prior(x) + log_jac
        return np.column_stack([log_post, x[:, 0]])


def test_walkers_start_in_every_basin_in_proportion_to_its_mass():
    rng = np.random.default_rng(4)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(2))
    toy = TwoModeToy(space)
    settings = SamplerSettings(
        n_walkers=40, max_steps=600, polish=16, mode_window=5.0,
        importance=ImportanceSettings(draws=0),  # the walkers' own draws are judged
    )  # fmt: skip
    run = run_sampler(toy, space, rng, settings)
    assert run.start_modes == 2
    first = run.chain[run.burn :, :, 0]  # the basins lie either side of u = 0
    assert abs(np.mean(first < 0) - 0.7) < 0.1  # one basin alone would give 0 or 1
    single = run_sampler(toy, space, rng, replace(settings, polish=3, mode_window=0.0))
    assert single.start_modes == 1
    assert np.mean(single.chain[single.burn :, :, 0] < 0) in (0.0, 1.0)


def test_walkers_start_in_every_basin_given_and_skip_one_outside_the_support():
    """``start`` as several optima: one whose log-probability is −inf (here NaN
    coordinates) gets no walkers; the others share them."""
    rng = np.random.default_rng(9)
    space = ParameterSpace(Parameter(f"t{i}", "1", Uniform(-20.0, 20.0)) for i in range(3))
    toy = LinearGaussianToy(space, rng)
    settings = SamplerSettings(n_walkers=16, max_steps=1, check_every=1)
    centre = space.to_unbounded(toy.truth[None, :])[0]
    outside = np.full(3, np.nan)
    run = run_sampler(
        toy,
        space,
        rng,
        settings,
        start=np.array([centre, outside]),
    )
    assert run.chain.shape[1] == 16 and np.all(np.isfinite(run.chain))
