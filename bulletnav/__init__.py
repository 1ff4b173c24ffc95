"""bulletnav."""
