"""Materials: strain energy density, first Piola-Kirchhoff stress and its tangent per
quadrature point (`hyperelastic`), built from the scene's [material] (`build`)."""
