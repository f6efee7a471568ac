import sys

from bstool.cli import main

sys.exit(main())
