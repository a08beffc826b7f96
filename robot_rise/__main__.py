import sys

from robot_rise.cli import main

sys.exit(main())
