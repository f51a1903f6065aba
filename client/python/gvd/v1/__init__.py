"""gvd.v1: the messages of gvd-server's API (voronoi_pb2), generated from the repository's
proto/gvd/v1/voronoi.proto by protoc 3.21 and kept here, so that the package builds from this
folder alone (tests/python/check_messages.sh checks they are fresh)."""
