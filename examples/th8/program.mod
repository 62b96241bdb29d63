MODULE Th8Demo
  ! A short RAPID module for the SIMULATED TH8-like robot (model.yaml), written for robocal's
  ! examples: joint targets in deg and mm (axes 2 and 3 are linear), Cartesian targets of the tool
  ! point (tSphere) in the robot's base frame. robocal compensate rewrites only the targets' numbers.
  PERS tooldata tSphere := [TRUE, [[30, 0, 120], [1, 0, 0, 0]], [1, [0, 0, 50], [1, 0, 0, 0], 0, 0, 0]];
  CONST jointtarget jP02 := [[-97.3, 604.2, 324.84, -68.1, -17.008, -169.804], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST jointtarget jP03 := [[-112.72, 469.4, 388.32, 39.23, -25.59, 178.996], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST robtarget pP04 := [[628.819, 962.752, 1135.675], [0.60567238, -0.21424784, 0.51775276, 0.56496983],
                           [1, 0, -2, 3], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  CONST robtarget pP05 := [[375.660, -912.608, 929.978], [0.51983679, 0.58112985, -0.52173868, 0.34618861],
                           [0, 0, 0, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];

  PROC main()
    MoveAbsJ jP02, v500, fine, tool0;
    MoveAbsJ jP03, v500, fine, tool0;
    MoveJ pP04, v500, z10, tSphere;
    MoveL pP05, v200, fine, tSphere;
    MoveL [[-732.074, -846.927, 970.666], [-0.06755061, -0.01203784, -0.32773817, 0.94227369], [-1, -2, -1, 0],
           [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]], v200, fine, tSphere;
  ENDPROC
ENDMODULE
