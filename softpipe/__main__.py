import sys

from softpipe.tools.cli import main

sys.exit(main())
