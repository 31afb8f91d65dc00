"""`python -m mog_drake.cli`."""

import sys

from mog_drake.cli import main

sys.exit(main())
