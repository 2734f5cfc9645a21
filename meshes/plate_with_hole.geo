// A 0.2 (x) x 0.1 (y) x 0.01 (z, thickness) plate with a circular through hole of radius
// 0.01 at its centre (0.1, 0.05), along z. Lengths in the case's units.
// Named faces: left (x = 0), right (x = 0.2), front (y = 0), back (y = 0.1), bottom (z = 0),
// top (z = 0.01), hole; volume: solid.
// Sizes: Mesh.MeshSizeMax 0.006 away from the hole; a Distance + Threshold field (from the
// hole's surface) asks for 0.002 within 0.003 of the hole, growing by 0.25 per unit
// distance beyond (0.006 at 0.019, 0.0285 at 0.11 from it). The size used is
// min(field, MeshSizeMax): an element_size passed to fem_frac replaces MeshSizeMax, so it
// coarsens or refines the far field and keeps the hole refinement while it is above 0.002
// (below that the mesh is uniform at element_size; fem_frac then also sizes by curvature,
// 12 elements per 2*pi).
SetFactory("OpenCASCADE");

lx = 0.2; ly = 0.1; lz = 0.01;                   // length, width, thickness
cx = lx / 2; cy = ly / 2; r = 0.01;              // hole centre and radius

Box(1) = {0, 0, 0, lx, ly, lz};
Cylinder(2) = {cx, cy, -lz, 0, 0, 3 * lz, r};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };

e = 1e-6;
Physical Surface("left") = Surface In BoundingBox{-e, -e, -e, e, ly + e, lz + e};
Physical Surface("right") = Surface In BoundingBox{lx - e, -e, -e, lx + e, ly + e, lz + e};
Physical Surface("front") = Surface In BoundingBox{-e, -e, -e, lx + e, e, lz + e};
Physical Surface("back") = Surface In BoundingBox{-e, ly - e, -e, lx + e, ly + e, lz + e};
Physical Surface("bottom") = Surface In BoundingBox{-e, -e, -e, lx + e, ly + e, e};
Physical Surface("top") = Surface In BoundingBox{-e, -e, lz - e, lx + e, ly + e, lz + e};
hole() = Surface In BoundingBox{cx - r - e, cy - r - e, -e, cx + r + e, cy + r + e, lz + e};
Physical Surface("hole") = {hole()};
Physical Volume("solid") = {3};

// refinement around the hole
Field[1] = Distance;
Field[1].SurfacesList = {hole()};
Field[1].Sampling = 60;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = 0.002;
Field[2].DistMin = 0.003;
Field[2].SizeMax = 0.002 + 0.25 * 0.106;
Field[2].DistMax = 0.003 + 0.106;
Background Field = 2;

Mesh.MeshSizeMax = 0.006;
Mesh.MeshSizeExtendFromBoundary = 0;
