"""Allow ``python -m oed``."""

import sys

try:
    from oed.cli import main
except KeyboardInterrupt:  # Ctrl-C while Python imports the command line: one line, no traceback
    print("oed: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
