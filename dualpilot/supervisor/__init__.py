"""The supervisory controller (Sec. III-C): attention and decision dynamics."""
