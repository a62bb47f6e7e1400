# The golden fixture comes from softpipe's pytest plugin. Installed softpipe enables it
# by itself (a pytest11 entry point); this line enables it when it is not installed,
# e.g. for `pytest examples/testing` from a checkout.
pytest_plugins = ["softpipe.testing.plugin"]
