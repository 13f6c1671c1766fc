"""Built-in case studies of parley (installed as the package ``parley_plugins``)."""
