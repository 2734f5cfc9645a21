// A pre-cracked double cantilever beam (DCB) for mode-I crack growth: L (x, length) x b
// (y, width) x 2 h (z, two arms of height h). The pre-crack is a slit in the mid-plane z = h
// from the loaded end x = 0 to the tip line x = a0; ahead of it the mid-plane is a mesh
// surface (faces of the mesh), so a mode-I crack grows along mesh faces. Lengths in the
// case's units (metres).
//
// The slit: its two flanks are separate surfaces that share only the tip line. So that
// gmsh's geometry coherence (which merges points at the same place) keeps them apart, the
// flanks sit at z = h +/- e at x = 0 and close linearly to z = h at the tip (e = 1e-4 h: a
// wedge of opening 2 um at the loaded end, far below any opening of the run). The arms lean
// with the flanks by e / a0, so a force along them has a small z share on the load faces
// (2.4 mN for the case's compression: tests/test_dcb.py subtracts it).
//
// The mesh is structured and extruded from the mid-plane: in x, uniform elements of size s
// over [a0 - 8 s, xf] (where the crack runs) and of size about sa elsewhere; across the width
// one element (with nu = 0 the problem does not depend on y: see docs/fracture/dcb.md); in z,
// next to the mid-plane above and below, a band of ONE layer of thickness s (volume
// groups band_top, band_bottom), then the rest of each arm, h - s, in 4 layers growing
// away from the crack (bulk_top, bulk_bottom). Every volume is a stack of prisms split
// into tets, mirror-symmetric about z = h. Protecting the bulk volumes in the case leaves
// only the mid-plane vertices free to split: cracks can run in the mid-plane only.
// An element_size in the case has no effect on this structured mesh: to refine, change s.
//
// Named faces (each boundary face in exactly one group):
//   load_top    = x = 0, z > h (the upper arm's end face)
//   load_bottom = x = 0, z < h (the lower arm's end face)
//   support     = x = L (the far end, both arms)
//   slit_top, slit_bottom: the pre-crack's flanks (upper, lower arm)
//   top (z = 2h), bottom (z = 0), front (y = 0), back (y = b)
// Volumes: band_top, band_bottom, bulk_top, bulk_bottom.

L = 0.09; b = 0.001; h = 0.01;      // length, width, arm height
a0 = 0.04;                          // pre-crack length (load line x = 0 to the tip)
s = 0.001;                          // element size along the crack path (and band thickness)
sa = 0.0025;                        // element size in x away from it
xf = 0.065;                         // the fine elements end here
e = 1e-6;                           // half opening of the slit at x = 0

xs = a0 - 8 * s;                    // the fine elements start here
n1 = Ceil(xs / sa);                 // divisions of [0, xs]
n2 = 8;                             // of [xs, a0]
n3 = Round((xf - a0) / s);          // of [a0, xf]
n4 = Ceil((L - xf) / sa);           // of [xf, L]

// the mid-plane. Upper flank: 1-9-2-5-10-6; lower flank: 7-11-2-5-12-8 (the tip line 2-5
// shared); ligament: 2-3-13-14-4-5 (3 and 4 at xf, 13 and 14 at L)
Point(1) = {0, 0, h + e};   Point(6) = {0, b, h + e};
Point(7) = {0, 0, h - e};   Point(8) = {0, b, h - e};
Point(9) = {xs, 0, h + e * (1 - xs / a0)};  Point(10) = {xs, b, h + e * (1 - xs / a0)};
Point(11) = {xs, 0, h - e * (1 - xs / a0)}; Point(12) = {xs, b, h - e * (1 - xs / a0)};
Point(2) = {a0, 0, h};      Point(5) = {a0, b, h};
Point(3) = {xf, 0, h};      Point(4) = {xf, b, h};
Point(13) = {L, 0, h};      Point(14) = {L, b, h};

// upper flank: [0, xs] then [xs, a0]
Line(1) = {1, 9};   Line(2) = {9, 10};  Line(3) = {10, 6};  Line(4) = {6, 1};
Line(5) = {9, 2};   Line(6) = {2, 5};   Line(7) = {5, 10};
// lower flank
Line(11) = {7, 11}; Line(12) = {11, 12}; Line(13) = {12, 8}; Line(14) = {8, 7};
Line(15) = {11, 2}; Line(17) = {5, 12};
// ligament: [a0, xf] then [xf, L]
Line(21) = {2, 3};  Line(22) = {3, 4};  Line(23) = {4, 5};
Line(24) = {3, 13}; Line(25) = {13, 14}; Line(26) = {14, 4};

Transfinite Curve{1, -3, 11, -13} = n1 + 1;
Transfinite Curve{5, -7, 15, -17} = n2 + 1;
Transfinite Curve{21, -23} = n3 + 1;
Transfinite Curve{24, -26} = n4 + 1;
Transfinite Curve{2, 4, 6, 12, 14, 22, 25} = 2;

Curve Loop(1) = {1, 2, 3, 4};     Plane Surface(1) = {1};   // upper flank, coarse
Curve Loop(2) = {5, 6, 7, -2};    Plane Surface(2) = {2};   // upper flank, fine
Curve Loop(3) = {11, 12, 13, 14}; Plane Surface(3) = {3};   // lower flank, coarse
Curve Loop(4) = {15, 6, 17, -12}; Plane Surface(4) = {4};   // lower flank, fine
Curve Loop(5) = {21, 22, 23, -6}; Plane Surface(5) = {5};   // ligament, fine
Curve Loop(6) = {24, 25, 26, -22}; Plane Surface(6) = {6};  // ligament, coarse
Transfinite Surface{1, 2, 3, 4, 5, 6};

// the band (one layer of thickness s), then the bulk (4 layers over h - s, growing), up
// from the upper flank and the ligament, down from the lower flank and the ligament.
// Extrude returns, per surface: its top, its volume, then one side per curve (4 here).
bu[] = Extrude {0, 0, s} { Surface{1, 2, 5, 6}; Layers{1}; };
bd[] = Extrude {0, 0, -s} { Surface{3, 4, 5, 6}; Layers{1}; };
gu[] = Extrude {0, 0, h - s} { Surface{bu[0], bu[6], bu[12], bu[18]};
                               Layers{{1, 1, 1, 1}, {0.1, 0.25, 0.5, 1}}; };
gd[] = Extrude {0, 0, -(h - s)} { Surface{bd[0], bd[6], bd[12], bd[18]};
                                  Layers{{1, 1, 1, 1}, {0.1, 0.25, 0.5, 1}}; };

Physical Volume("band_top") = {bu[1], bu[7], bu[13], bu[19]};
Physical Volume("band_bottom") = {bd[1], bd[7], bd[13], bd[19]};
Physical Volume("bulk_top") = {gu[1], gu[7], gu[13], gu[19]};
Physical Volume("bulk_bottom") = {gd[1], gd[7], gd[13], gd[19]};

t = 1e-5;
Physical Surface("load_top") = Surface In BoundingBox{-t, -t, h + e / 2, t, b + t, 2 * h + t};
Physical Surface("load_bottom") = Surface In BoundingBox{-t, -t, -t, t, b + t, h - e / 2};
Physical Surface("support") = Surface In BoundingBox{L - t, -t, -t, L + t, b + t, 2 * h + t};
Physical Surface("slit_top") = {1, 2};
Physical Surface("slit_bottom") = {3, 4};
Physical Surface("top") = Surface In BoundingBox{-t, -t, 2 * h - t, L + t, b + t, 2 * h + t};
Physical Surface("bottom") = Surface In BoundingBox{-t, -t, -t, L + t, b + t, t};
Physical Surface("front") = Surface In BoundingBox{-t, -t, -t, L + t, t, 2 * h + t};
Physical Surface("back") = Surface In BoundingBox{-t, b - t, -t, L + t, b + t, 2 * h + t};
