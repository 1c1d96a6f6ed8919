"""``python -m pbrcheck_cli``: the ``pbrcheck`` console script."""

import sys

from . import main

sys.exit(main())
