"""The material classifiers' timing features: what a slower loading and a larger force do to them."""

import numpy as np

from neurotac_cli.model import material


def grasp(rise_frames: int, force: float, frames: int = 60) -> tuple:
    """Per-frame ON and OFF counts of a grasp: an LED OFF spike in frame 0, ON events over a loading
    of `rise_frames` frames growing with the force, a few events while held, OFF events on release."""
    rates = np.zeros((frames, 2))
    rates[0, 1] = 500.0
    rates[5:5 + rise_frames, 0] = force * 100.0 / rise_frames
    rates[5 + rise_frames:45, 0] = force * 0.5
    rates[45:50, 1] = force * 80.0 / 5
    pixels = np.zeros((frames, 2, 16))
    pixels[:, :, :4] = rates[:, :, None] / 4
    return rates, pixels.reshape(frames, -1)


def test_a_slower_loading_delays_every_rise_time_and_the_force_leaves_them_alone():
    fast, slow = (material.dynamics(grasp(rise, 2.0)[0]) for rise in (3, 9))
    assert fast.shape == (material.DYNAMICS,)
    assert (slow[:6] > fast[:6]).all()  # 10-70% of the ON events come later into a softer object
    weak, strong = (material.dynamics(grasp(5, force)[0]) for force in (1.0, 4.0))
    np.testing.assert_allclose(weak[:6], strong[:6], atol=1e-9)  # timing does not follow the amount
    assert strong[6] > weak[6]  # the amount does


def test_the_led_spike_before_the_loading_is_not_counted_as_release():
    rates, _ = grasp(5, 2.0)
    without = rates.copy()
    without[0, 1] = 0.0
    np.testing.assert_allclose(material.dynamics(rates), material.dynamics(without))


def test_a_trial_without_events_gives_zeros_and_widths_match_the_features():
    assert not material.dynamics(np.zeros((10, 2))).any()
    counts = grasp(5, 2.0)[1]
    for inputs in ("timing", "curves"):
        config = material.Config(inputs=inputs)
        x = material._trial_features(counts, np.zeros(60), config)
        assert x.shape == (material.feature_count(config),) and np.isfinite(x).all()


def test_the_discriminant_separates_classes_that_differ_along_a_correlated_direction():
    rng = np.random.default_rng(0)
    shared = rng.standard_normal((200, 1))
    z = np.hstack([shared, shared + 0.05 * rng.standard_normal((200, 1))])  # two nearly equal features
    y = np.repeat([0, 1], 100)
    z[y == 1, 1] += 0.3  # the classes differ only in the small difference between them
    weight, bias = material.discriminant(z, y, 3)
    predicted = np.argmax(z @ weight.T + bias, axis=1)
    assert (predicted == y).mean() > 0.95
    assert bias[2] < -1e8  # a class absent from training never wins
