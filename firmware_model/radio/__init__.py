"""The radio side of the child firmware: wire format, deframer, Content, checksum, MAC."""

PROTOCOL_VERSION = "3.7"
"""The radio protocol version these modules implement (docs/protocol.md §0; not on the wire)."""
