// The notched beam of meshes/notched_beam_cohesive.geo (0.17 x 0.005 x 0.04, span 0.16, a
// sharp V notch 0.02 deep at mid-span x = 0.085, the ligament x = 0.085, z in [0.02, 0.04] a
// mesh surface) with line supports instead of strips: the lines x = 0.005 and x = 0.165 on
// the bottom face and the ligament's top edge (x = 0.085, z = 0.04) are mesh edges, so a
// case can hold the nodes along them (boundary_conditions with 'vertices') and each half
// of the broken beam turns freely about its lines, as about the rollers of a test rig.
//
// Named faces: xmin, xmax, front (y = 0), back (y = 0.005), bottom (z = 0), top (z = 0.04),
// notch (the V's flanks); volumes: left (x < 0.085), right (x > 0.085), solid = both.
//
// Sizes: uniform (fem_frac passes element_size as Mesh.MeshSizeMax). Tets (HXT, one
// thread): element_size 0.01 -> 742, 0.005 -> 2,305, 0.0025 -> 11,724; the ligament is 2,
// 4 and 8 edges deep, and the support and load lines carry 2, 2 and 3 nodes.
SetFactory("OpenCASCADE");

lx = 0.17; ly = 0.005; lz = 0.04;                // length, thickness, height
xm = 0.085;                                      // mid-span: the ligament plane
nd = 0.02; nm = 0.005;                           // notch depth, mouth width
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

// the ligament plane, imprinted as a mesh surface (its top edge is the load line)
lig = news; Rectangle(lig) = {0, 0, 0, lz - nd, ly};
Rotate {{0, 1, 0}, {0, 0, 0}, -Pi / 2} { Surface{lig}; }  // now in the plane x = 0 (y, z)
Translate {xm, 0, nd} { Surface{lig}; }
// the support lines on the bottom face, imprinted as mesh edges
q1 = newp; Point(q1) = {s1, 0, 0};
q2 = newp; Point(q2) = {s1, ly, 0};
q3 = newp; Point(q3) = {s2, 0, 0};
q4 = newp; Point(q4) = {s2, ly, 0};
k1 = newl; Line(k1) = {q1, q2};
k2 = newl; Line(k2) = {q3, q4};
BooleanFragments{ Volume{3}; Delete; }{ Surface{lig}; Curve{k1, k2}; Delete; }

e = 1e-6;
bot() = Surface In BoundingBox{-e, -e, -e, lx + e, ly + e, e};
tp() = Surface In BoundingBox{-e, -e, lz - e, lx + e, ly + e, lz + e};
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
Physical Volume("left") = {vl()};
Physical Volume("right") = {vr()};
Physical Volume("solid") = {vl(), vr()};

Mesh.MeshSizeMax = 0.005;
Mesh.MeshSizeExtendFromBoundary = 0;   // no smaller sizes spread from short edges
Mesh.MeshSizeFromPoints = 0;
