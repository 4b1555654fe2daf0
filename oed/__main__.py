"""Allow ``python -m oed``."""

import sys

from oed.cli import main

sys.exit(main())
