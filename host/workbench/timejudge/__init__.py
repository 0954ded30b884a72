"""Time judged where the boat comes back: the revisits, the forms a change in time can take, the verdict and its words, and the water level checked at the crossings."""
