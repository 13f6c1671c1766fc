"""``python -m parley_core`` is the ``parley`` command."""

from parley_core.cli import main

if __name__ == "__main__":
    main()
