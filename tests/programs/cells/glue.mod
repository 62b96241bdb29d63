MODULE GlueCell
  ! A glue cell for the SIMULATED TH8-like robot of examples/th8: the bead's points in the part's
  ! work object, the glue gun's nozzle (the model's tool point), the approach through Offs, the
  ! departure through RelTool, a service position with tool0 (the flange).
  PERS tooldata tGlue := [TRUE, [[30, 0, 120], [1, 0, 0, 0]], [2.5, [0, 0, 60], [1, 0, 0, 0], 0, 0, 0]];
  PERS wobjdata wPart := [FALSE, TRUE, "", [[350, -250, 400], [0.96592583, 0.00000000, 0.00000000, 0.25881905]], [[0, 0, 0], [1, 0, 0, 0]]];
  CONST robtarget pStart := [[-371.039, -638.995, 562.366], [0.54498525, 0.73976463, -0.05048304, -0.39139599], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST robtarget pBead{5} := [
    [[-287.161, -693.724, 594.345], [0.55972653, 0.76414256, -0.16127402, -0.27709756], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]],
    [[-195.535, -705.403, 589.170], [0.56314225, 0.77411103, -0.16150074, -0.23987589], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]],
    [[-102.393, -709.051, 583.716], [0.56342430, 0.78446988, -0.16086801, -0.20317863], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]],
    [[-8.447, -704.466, 578.004], [0.56066411, 0.79516095, -0.15933604, -0.16729271], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]],
    [[85.560, -691.507, 572.060], [0.55497994, 0.80612336, -0.15686879, -0.13249372], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]]
  ];
  CONST robtarget pEnd := [[178.865, -670.103, 535.910], [0.54651559, 0.81729374, -0.15343418, -0.09904340], [0, 0, -1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST robtarget pService := [[-702.951, -482.453, 844.333], [0.38511270, 0.65436834, -0.59172399, 0.27083761], [-1, -1, 1, 1], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  VAR num i;

  PROC main()
    MoveJ Offs(pStart, 0, 0, 50), v500, z10, tGlue\WObj:=wPart;
    MoveL pStart, v200, fine, tGlue\WObj:=wPart;
    FOR i FROM 1 TO 5 DO
      MoveL pBead{i}, v100, z1, tGlue\WObj:=wPart;
    ENDFOR
    MoveL RelTool(pEnd, 0, 0, -30), v200, z10, tGlue\WObj:=wPart;
    MoveJ pService, v500, fine, tool0;
  ENDPROC
ENDMODULE
