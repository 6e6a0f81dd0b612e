"""The field deliverables of a shrub chain's folder: the offline web map, the 3D scene, the map book."""
