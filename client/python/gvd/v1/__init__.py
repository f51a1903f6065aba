"""gvd.v1: the messages of gvd-server's API, generated from proto/ when the package is built."""
