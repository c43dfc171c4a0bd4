"""One module per command: the layer that writes run folders and prints."""
