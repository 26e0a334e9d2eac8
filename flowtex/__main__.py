"""``python -m flowtex`` is the ``flowtex`` command."""

import sys

from .cli import main

sys.exit(main())
