"""``python -m drivers.mockbus``: serve an emulated bus on a pseudo-terminal (see pty_server)."""

import sys

from drivers.mockbus.pty_server import main

sys.exit(main())
