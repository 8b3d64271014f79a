"""The algorithm registry: every entry is an Algorithm object with consistent facts, and the
causal/offline queries that the node and replay rely on."""

from __future__ import annotations

import pytest

from gyro_attitude.core.attitude import (
    ALGORITHMS,
    DEFAULT_ALGORITHM,
    DEFAULT_OFFLINE_ALGORITHM,
    Algorithm,
    causal_algorithms,
    get_algorithm,
    integrate_batch,
    offline_algorithms,
)


def test_entries_are_algorithm_objects_named_by_their_key():
    for name, alg in ALGORITHMS.items():
        assert isinstance(alg, Algorithm) and alg.name == name
        assert alg.consumes in ("rate", "increment")
        assert alg.order >= 1 and alg.samples_per_update >= 1
        assert get_algorithm(name) is alg


def test_causal_and_offline_queries_partition_the_registry():
    causal, offline = causal_algorithms(), offline_algorithms()
    assert set(causal) | set(offline) == set(ALGORITHMS)
    assert not set(causal) & set(offline)
    assert all(a.causal for a in causal.values())
    assert "magnus6_quintic" in offline and "magnus6_quintic" not in causal
    assert DEFAULT_ALGORITHM == "rotvec_cubic" and DEFAULT_ALGORITHM in causal
    assert DEFAULT_OFFLINE_ALGORITHM == "magnus6_quintic"


@pytest.mark.parametrize("bad", ["magic", "", None, 3, "ROTVEC_CUBIC"])
def test_unknown_names_are_one_clear_value_error(bad):
    with pytest.raises(ValueError, match="unknown algorithm"):
        get_algorithm(bad)
    with pytest.raises(ValueError, match="unknown algorithm"):
        integrate_batch([0, 10], [[0.0, 0.0, 0.0]] * 2, algorithm=bad)
