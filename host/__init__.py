"""forcemap host side: the acquisition daemon on the boat's computer and the modelling workbench."""
