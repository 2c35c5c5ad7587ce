if __name__ != "softevo.migrations":  # installed as softevo.migrations (pyproject.toml): one name, one module
    raise ImportError(f"import softevo.migrations, not {__name__}")
