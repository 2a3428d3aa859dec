"""`python -m fourbar_ros.commands`: the `fourbar` command line."""

import sys

from fourbar_ros.commands import main

sys.exit(main())
