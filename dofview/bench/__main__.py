import sys

from dofview.bench.cli import main

sys.exit(main())
