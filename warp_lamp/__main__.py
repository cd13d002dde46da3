import sys

from warp_lamp.cli import main

sys.exit(main())
