"""The offline estimator runs without the compiler: with the precompiled rest loop
(``rest.rest_rows``, built by io/precompile) an aided offline replay (replay's default
algorithm, the vectorized magnus6_quintic) in a fresh process imports no numba (its import and
first cache load take longer than all the rest of such a replay); without it the loop is
compiled just in time, with the same results; and the covariance verdicts it judges once per
distinct row are every row's."""

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gyro_attitude.core import jit
from gyro_attitude.core.attitude import chain, rest
from gyro_attitude.core.attitude.stream import covariance_rows

REPO = Path(__file__).resolve().parents[3]

OFFLINE_RUN = """
import sys
import numpy as np
from gyro_attitude.core.attitude import DEFAULT_OFFLINE_ALGORITHM
from gyro_attitude.core.attitude.offline import estimate_offline
from gyro_attitude.core.attitude.settings import StreamConfig
n = 4000
t = (np.arange(1, n + 1) * 5_000_000).astype(np.int64)
rng = np.random.default_rng(1)
w = rng.normal(0.0, 1e-3, (n, 3)); w[1500:2500, 2] += 0.5
a = np.tile([0.3, -0.2, 9.79], (n, 1)) + rng.normal(0.0, 0.02, (n, 3))
cov = np.tile(np.diag([1e-6, 1e-6, 2e-6]).ravel(), (n, 1)); cov[::7, 0] = -1.0
res = estimate_offline(t, w, a, config=StreamConfig(aiding="auto"),
                       angular_velocity_covariance=cov, algorithm=DEFAULT_OFFLINE_ALGORITHM)
assert res.q.shape == (n, 4) and np.isfinite(res.q).all() and res.bias.rests_used > 0
print(",".join(m for m in sys.modules if m.split(".")[0] == "numba"))
print(res.q.tobytes().hex())
"""


def _offline_run(**env):
    out = subprocess.run([sys.executable, "-c", OFFLINE_RUN], capture_output=True, text=True,
                         timeout=300, cwd=REPO, check=True, env=dict(os.environ, **env)).stdout
    return out.split("\n")[:2]


def test_with_the_precompiled_rest_loop_an_aided_offline_estimate_loads_no_numba():
    if jit.precompiled(rest.rest_rows) is None:
        if os.environ.get("CI") == "true":
            pytest.fail("dev.sh builds the precompiled loops in CI (gyro_attitude.io.precompile)")
        pytest.skip("the precompiled rest loop is not built here")
    numba_modules, q = _offline_run()
    assert numba_modules == "", f"the offline estimate imported {numba_modules.split(',')[:4]}"
    numba_modules, q_jit = _offline_run(GYRO_ATTITUDE_PRECOMPILED="0")
    assert numba_modules != "" or jit.backend() == "python"  # the loop compiled just in time
    assert q_jit == q


def _row_by_row(cov):
    """The oracle: the causal step's verdict of each row on its own."""
    var = np.zeros((len(cov), 3))
    code = np.zeros(len(cov), np.int8)
    for k, row in enumerate(cov):
        code[k], var[k, 0], var[k, 1], var[k, 2] = chain.covariance_verdict(row)
    return var, code


@pytest.mark.parametrize("distinct", [1, 5, 5000])
def test_verdicts_judged_per_distinct_row_are_every_rows_verdict(distinct):
    rng = np.random.default_rng(distinct)
    table = np.zeros((distinct, 9))
    table[:, [0, 4, 8]] = rng.uniform(1e-8, 1e-4, (distinct, 3))
    table[0] = [-1.0] + [0.0] * 8                       # no estimate
    if distinct > 1:
        table[1] = 0.0                                   # unknown (all zeros)
        table[2, 4] = np.nan                             # invalid
    cov = table[rng.integers(0, distinct, 6000)]
    valid = np.arange(6000)
    counts, details = {}, {}
    var, known = covariance_rows(cov, valid, counts, details)
    var_o, code_o = _row_by_row(cov)
    np.testing.assert_array_equal(var, var_o)
    np.testing.assert_array_equal(known, code_o == chain.COV_KNOWN)
    assert sum(counts.values()) == int(np.count_nonzero(code_o == chain.COV_INVALID))
