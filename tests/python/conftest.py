import os
import sys
import warnings

import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

# the bundled Atlas has one link with a non-PSD inertia tensor (published
# data); the reader warns about it, which is expected in these tests
warnings.filterwarnings("ignore", message=".*not positive semi-definite.*")


def pytest_configure(config):
    config.addinivalue_line("filterwarnings", "ignore:.*not positive semi-definite.*:UserWarning")
