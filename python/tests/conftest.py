# SPDX-License-Identifier: BSD-3-Clause
"""The kumo program under test.

It is the one ``kumo.find_executable`` finds: ``$KUMO_EXE`` (scripts/test.sh sets it to the
build being tested), else ``kumo`` on PATH. Without one, the tests that run kumo fail with a
message saying so.
"""

import pytest

import kumo


@pytest.fixture(scope="session")
def exe():
    try:
        return kumo.find_executable()
    except kumo.KumoError as error:
        pytest.fail(f"{error} (these tests run the kumo program)")
