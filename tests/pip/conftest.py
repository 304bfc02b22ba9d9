# pytester runs inner pytest sessions (test_plugin.py)
pytest_plugins = ["pytester"]
