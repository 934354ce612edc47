import sys

from carbody.cli import main

sys.exit(main())
