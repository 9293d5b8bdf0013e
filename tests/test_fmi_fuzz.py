"""The FMI surface of each FMU fuzzed through FMPy (tests/fmi_fuzz.py says what must hold); the
long run, >= 10 000 sequences, is benchmarks/fmi_fuzz.py."""
from __future__ import annotations

import pytest
from hypothesis import HealthCheck, given, settings

from fmi_fuzz import Unpacked, check, sequences
from suspension_estimation.suspension_fmi.contract import CONTRACTS

SHORT = settings(derandomize=True, database=None, deadline=None, max_examples=25,
                 suppress_health_check=list(HealthCheck))


@pytest.fixture(scope="module", params=list(CONTRACTS))
def unpacked(request, dist):
    u = Unpacked(dist / f"{request.param}.fmu")
    yield u
    u.close()


def test_random_fmi_call_sequences_never_fatal(unpacked):
    @SHORT
    @given(seq=sequences(unpacked))
    def run(seq):
        initialized, calls = seq
        check(unpacked, initialized, calls)

    run()
