"""Chapter 1, curve fitting: y = exp(a x^2 + b x + c), its data and problem."""
