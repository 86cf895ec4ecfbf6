"""Rankings: how a scored generation becomes the order selection reads."""
