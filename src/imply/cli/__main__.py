"""``python -m imply.cli``: the same as the ``imply`` console script."""

import sys

from imply.cli import main

sys.exit(main())
