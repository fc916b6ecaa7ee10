"""Materials: energy densities W(F) with P = dW/dF and dP/dF (elastomers, the PNIPAM gel) and the
gel's material-point swelling. The lowest layer: it imports nothing else of hydrojam."""
