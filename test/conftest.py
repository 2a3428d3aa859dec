"""Shared pytest setup: test helpers importable as plain modules; hypothesis made deterministic.

Property tests draw the same examples on every run (derandomize), so CI cannot pass or fail by luck. Set
HYPOTHESIS_PROFILE=explore to search with fresh random examples locally.
"""

import os
import sys
from pathlib import Path

from hypothesis import settings

sys.path.insert(0, str(Path(__file__).parent))

settings.register_profile('deterministic', derandomize=True, deadline=None, print_blob=True)
settings.register_profile('explore', derandomize=False, deadline=None, print_blob=True)
settings.load_profile(os.environ.get('HYPOTHESIS_PROFILE', 'deterministic'))
