"""YAML to validated scenario models to physics objects."""
