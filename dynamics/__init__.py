"""Robot descriptions and symbolic identification models (CasADi)."""
