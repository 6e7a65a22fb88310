"""A plugin module that ends the interpreter when it is imported (tests/test_plugins.py): loading
it must cost that plugin only, never the command that reads the library."""

import sys

sys.exit(3)
