import sys

from chekhov.cli import main

sys.exit(main())
