import sys

from dofview.cli import main

sys.exit(main())
