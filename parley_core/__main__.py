"""``python -m parley_core`` is the ``parley`` command (guarded: :mod:`parley_core.guard`)."""

from parley_core.guard import main

if __name__ == "__main__":
    main()
