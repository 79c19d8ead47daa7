"""Input and output: scenario folders, ASTERIX, recordings and their conversion, one door for every source."""
