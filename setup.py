"""Package discovery, the one thing pyproject.toml cannot say: parley (the library API),
parley_core and its sub-packages, and the built-in plugins of plugins/ installed as parley_plugins (their
tests stay in the repository)."""

from setuptools import find_packages, setup

core = ["parley", *find_packages(include=["parley_core", "parley_core.*"])]
plugins = [
    "parley_plugins" + name[len("plugins") :]
    for name in find_packages(include=["plugins", "plugins.*"], exclude=["*.tests", "*.tests.*"])
]
setup(packages=core + plugins, package_dir={"parley_plugins": "plugins"})
