// A thin single-edge-notched beam for three-point bending with cohesive cracks:
// 0.17 (x) x 0.005 (y, thickness) x 0.04 (z, height), span 0.16 between the support strips,
// a sharp V notch at mid-span x = 0.085 cut from the bottom face through the full thickness:
// mouth 0.005 wide at z = 0, tip (a straight edge along y) at z = 0.02, so the ligament is
// the rectangle x = 0.085, z in [0.02, 0.04], 0.02 x 0.005. Lengths in the case's units.
//
// The ligament plane is a mesh surface: the beam is built as two halves glued with
// BooleanFragments along the rectangle x = 0.085, z in [0.02, 0.04] (the notch tip edge is
// its lower side), so every tet has its faces on one side of that plane and a mode-I crack
// can run along mesh faces from the notch tip straight up to the top face.
//
// Named faces (every boundary face is in exactly one group):
//   xmin (x = 0), xmax (x = 0.17), front (y = 0), back (y = 0.005),
//   support_left  = bottom strip x in [0.00375, 0.00625] (z = 0),
//   support_right = bottom strip x in [0.16375, 0.16625] (z = 0),
//   load          = top strip    x in [0.08375, 0.08625] (z = 0.04; two faces, one per half),
//   bottom (z = 0, both sides of the notch) and top (z = 0.04): the rest of those faces,
//   notch (the two flanks of the V);
// volumes: left (x < 0.085) and right (x > 0.085); solid = both.
//
// Sizes: uniform. fem_frac passes the case's element_size as Mesh.MeshSizeMax, which caps
// every size gmsh uses (fields included), so a band refined around the ligament with a
// coarser far field cannot be tied to element_size; the beam is kept small and thin
// instead, and element_size is the size everywhere, along the crack path in particular.
// (The strips, 0.0025 wide, and the notch mouth, 0.005, ask for elements that small on the
// faces near them when element_size is larger.) Tets (HXT, one thread): element_size 0.01
// -> 756, 0.005 -> 2,398, 0.0025 -> 11,658; the ligament is then 2, 4 and 8 edges deep.
SetFactory("OpenCASCADE");

lx = 0.17; ly = 0.005; lz = 0.04;                // length, thickness, height
xm = 0.085;                                      // mid-span: the ligament plane
nd = 0.02; nm = 0.005;                           // notch depth, mouth width
ws = 0.0025;                                     // width of the support and load strips
s1 = 0.005; s2 = 0.165;                          // support lines (span 0.16)

Box(1) = {0, 0, 0, lx, ly, lz};
// the V notch: a triangle in the plane y = -ly, extruded through the thickness (and beyond)
p1 = newp; Point(p1) = {xm - nm / 2, -ly, -nd};
p2 = newp; Point(p2) = {xm + nm / 2, -ly, -nd};
p3 = newp; Point(p3) = {xm + nm / 2, -ly, 0};
p4 = newp; Point(p4) = {xm, -ly, nd};
p5 = newp; Point(p5) = {xm - nm / 2, -ly, 0};
l1 = newl; Line(l1) = {p1, p2};
l2 = newl; Line(l2) = {p2, p3};
l3 = newl; Line(l3) = {p3, p4};
l4 = newl; Line(l4) = {p4, p5};
l5 = newl; Line(l5) = {p5, p1};
c1 = newcl; Curve Loop(c1) = {l1, l2, l3, l4, l5};
f1 = news; Plane Surface(f1) = {c1};
v() = Extrude {0, 3 * ly, 0} { Surface{f1}; };
BooleanDifference(3) = { Volume{1}; Delete; }{ Volume{v(1)}; Delete; };

// the ligament plane, the strips as rectangles imprinted on the bottom and top faces
lig = news; Rectangle(lig) = {0, 0, 0, lz - nd, ly};
Rotate {{0, 1, 0}, {0, 0, 0}, -Pi / 2} { Surface{lig}; }  // now in the plane x = 0 (y, z)
Translate {xm, 0, nd} { Surface{lig}; }
r1 = news; Rectangle(r1) = {s1 - ws / 2, 0, 0, ws, ly};
r2 = news; Rectangle(r2) = {s2 - ws / 2, 0, 0, ws, ly};
r3 = news; Rectangle(r3) = {xm - ws / 2, 0, lz, ws, ly};
BooleanFragments{ Volume{3}; Delete; }{ Surface{lig, r1, r2, r3}; Delete; }

e = 1e-6;
sl() = Surface In BoundingBox{s1 - ws / 2 - e, -e, -e, s1 + ws / 2 + e, ly + e, e};
sr() = Surface In BoundingBox{s2 - ws / 2 - e, -e, -e, s2 + ws / 2 + e, ly + e, e};
ld() = Surface In BoundingBox{xm - ws / 2 - e, -e, lz - e, xm + ws / 2 + e, ly + e, lz + e};
bot() = Surface In BoundingBox{-e, -e, -e, lx + e, ly + e, e};
bot() -= {sl(), sr()};
tp() = Surface In BoundingBox{-e, -e, lz - e, lx + e, ly + e, lz + e};
tp() -= {ld()};
// the notch flanks: the faces inside the notch's bounding box that are neither the bottom
// nor the ligament plane (which is an interior face, in no group)
nt() = Surface In BoundingBox{xm - nm / 2 - e, -e, -e, xm + nm / 2 + e, ly + e, nd + e};
nt() -= {bot()};
vl() = Volume In BoundingBox{-e, -e, -e, xm + e, ly + e, lz + e};
vr() = Volume In BoundingBox{xm - e, -e, -e, lx + e, ly + e, lz + e};

Physical Surface("xmin") = Surface In BoundingBox{-e, -e, -e, e, ly + e, lz + e};
Physical Surface("xmax") = Surface In BoundingBox{lx - e, -e, -e, lx + e, ly + e, lz + e};
Physical Surface("front") = Surface In BoundingBox{-e, -e, -e, lx + e, e, lz + e};
Physical Surface("back") = Surface In BoundingBox{-e, ly - e, -e, lx + e, ly + e, lz + e};
Physical Surface("bottom") = {bot()};
Physical Surface("top") = {tp()};
Physical Surface("notch") = {nt()};
Physical Surface("support_left") = {sl()};
Physical Surface("support_right") = {sr()};
Physical Surface("load") = {ld()};
Physical Volume("left") = {vl()};
Physical Volume("right") = {vr()};
Physical Volume("solid") = {vl(), vr()};

Mesh.MeshSizeMax = 0.005;
Mesh.MeshSizeExtendFromBoundary = 0;   // no smaller sizes spread from short edges
Mesh.MeshSizeFromPoints = 0;
