// A single-edge-notched beam for three-point bending: 0.2 (x) x 0.02 (y, thickness) x 0.04
// (z, height), with a slot 0.002 wide (x in [0.099, 0.101]) and 0.01 deep (z in [0, 0.01])
// cut from the bottom face at mid-span through the full thickness; the notch root is the
// face z = 0.01 of the slot. Lengths in the case's units.
// Named faces:
//   xmin (x = 0), xmax (x = 0.2), front (y = 0), back (y = 0.02),
//   support_left  = bottom strip x in [0.01, 0.02]   (z = 0),
//   support_right = bottom strip x in [0.18, 0.19]   (z = 0),
//   load          = top strip    x in [0.095, 0.105] (z = 0.04),
//   bottom (z = 0, both sides of the notch) and top (z = 0.04): the rest of those faces,
//          WITHOUT the strips (every boundary face is in exactly one group),
//   notch  (the slot's three faces: x = 0.099, x = 0.101 and the root z = 0.01);
// volume: solid (one volume: the strips are imprinted with BooleanFragments).
// Sizes: Mesh.MeshSizeMax 0.0045 away from the notch; a Distance + Threshold field (from the
// edges of the notch root face) asks for 0.0015 within 0.01 of the root, growing by 0.25 per
// unit distance beyond (0.0045 at 0.022, 0.006 at 0.028 from the root, 0.0265 at 0.11).
// The size used is min(field, MeshSizeMax): an element_size passed to fem_frac replaces
// MeshSizeMax, so it coarsens or refines the far field and keeps the notch refinement while
// it is above 0.0015 (below that the mesh is uniform at element_size).
SetFactory("OpenCASCADE");

lx = 0.2; ly = 0.02; lz = 0.04;                  // length, thickness, height
nx = 0.1; nw = 0.002; nd = 0.01;                 // notch centre, width, depth
s1 = 0.01; s2 = 0.02; s3 = 0.18; s4 = 0.19;      // support strips [s1, s2], [s3, s4]
l1 = 0.095; l2 = 0.105;                          // load strip [l1, l2]

Box(1) = {0, 0, 0, lx, ly, lz};
Box(2) = {nx - nw / 2, -ly / 2, -nd, nw, 2 * ly, 2 * nd};
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{2}; Delete; };
// strips as rectangles in the planes z = 0 and z = lz, imprinted on the faces
r1 = news; Rectangle(r1) = {s1, 0, 0, s2 - s1, ly};
r2 = news; Rectangle(r2) = {s3, 0, 0, s4 - s3, ly};
r3 = news; Rectangle(r3) = {l1, 0, lz, l2 - l1, ly};
BooleanFragments{ Volume{3}; Delete; }{ Surface{r1, r2, r3}; Delete; }

e = 1e-6;
sl() = Surface In BoundingBox{s1 - e, -e, -e, s2 + e, ly + e, e};
sr() = Surface In BoundingBox{s3 - e, -e, -e, s4 + e, ly + e, e};
ld() = Surface In BoundingBox{l1 - e, -e, lz - e, l2 + e, ly + e, lz + e};
bot() = Surface In BoundingBox{-e, -e, -e, lx + e, ly + e, e};
bot() -= {sl(), sr()};
tp() = Surface In BoundingBox{-e, -e, lz - e, lx + e, ly + e, lz + e};
tp() -= {ld()};

Physical Surface("xmin") = Surface In BoundingBox{-e, -e, -e, e, ly + e, lz + e};
Physical Surface("xmax") = Surface In BoundingBox{lx - e, -e, -e, lx + e, ly + e, lz + e};
Physical Surface("front") = Surface In BoundingBox{-e, -e, -e, lx + e, e, lz + e};
Physical Surface("back") = Surface In BoundingBox{-e, ly - e, -e, lx + e, ly + e, lz + e};
Physical Surface("bottom") = {bot()};
Physical Surface("top") = {tp()};
Physical Surface("notch") = Surface In BoundingBox{nx - nw / 2 - e, -e, -e,
                                                   nx + nw / 2 + e, ly + e, nd + e};
Physical Surface("support_left") = {sl()};
Physical Surface("support_right") = {sr()};
Physical Surface("load") = {ld()};
Physical Volume("solid") = Volume In BoundingBox{-e, -e, -e, lx + e, ly + e, lz + e};

// refinement around the notch root: the edges of the slot's face z = nd
root() = Curve In BoundingBox{nx - nw / 2 - e, -e, nd - e, nx + nw / 2 + e, ly + e, nd + e};
Field[1] = Distance;
Field[1].CurvesList = {root()};
Field[1].Sampling = 40;
Field[2] = Threshold;
Field[2].InField = 1;
Field[2].SizeMin = 0.0015;
Field[2].DistMin = 0.01;
Field[2].SizeMax = 0.0015 + 0.25 * 0.1;
Field[2].DistMax = 0.01 + 0.1;
Background Field = 2;

Mesh.MeshSizeMax = 0.0045;
Mesh.MeshSizeExtendFromBoundary = 0;
