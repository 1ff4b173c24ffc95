"""``python -m bulletnav.cli``: the ``bulletnav`` command."""

import sys

from bulletnav.cli import main

if __name__ == "__main__":
    sys.exit(main())
