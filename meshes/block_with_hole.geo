// A 2 x 1 x 0.5 block with a cylindrical hole of radius 0.25 through it along z.
// Named faces: left (x = 0), right (x = 2), front (y = 0), back (y = 1), bottom (z = 0),
// top (z = 0.5), hole; volume: solid. Lengths in the case's units.
// block_with_hole.msh (4611 tets) was made with gmsh 4.15 (HXT, one thread: repeatable):
//   gmsh block_with_hole.geo -3 -algo hxt -nt 1 -format msh41 -o block_with_hole.msh
SetFactory("OpenCASCADE");

lx = 2.0; ly = 1.0; lz = 0.5; r = 0.25;
Box(1) = {0, 0, 0, lx, ly, lz};
Cylinder(2) = {lx / 2, ly / 2, -lz, 0, 0, 3 * lz, r};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };

e = 1e-6;
Physical Surface("left") = Surface In BoundingBox{-e, -e, -e, e, ly + e, lz + e};
Physical Surface("right") = Surface In BoundingBox{lx - e, -e, -e, lx + e, ly + e, lz + e};
Physical Surface("front") = Surface In BoundingBox{-e, -e, -e, lx + e, e, lz + e};
Physical Surface("back") = Surface In BoundingBox{-e, ly - e, -e, lx + e, ly + e, lz + e};
Physical Surface("bottom") = Surface In BoundingBox{-e, -e, -e, lx + e, ly + e, e};
Physical Surface("top") = Surface In BoundingBox{-e, -e, lz - e, lx + e, ly + e, lz + e};
Physical Surface("hole") = Surface In BoundingBox{lx/2 - r - e, ly/2 - r - e, -e,
                                                  lx/2 + r + e, ly/2 + r + e, lz + e};
Physical Volume("solid") = {3};

Mesh.MeshSizeMax = 0.1;
Mesh.MeshSizeFromCurvature = 12;
