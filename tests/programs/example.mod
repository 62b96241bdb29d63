%%%
  VERSION:1
  LANGUAGE:ENGLISH
%%%

MODULE PickPlace
  ! Targets for the arm6r test robot (tests/robots.py) and its tool point, in its base frame.
  ! Written by hand: every declaration kind, continuation lines, external axes.
  TASK PERS tooldata tGripper := [TRUE, [[50, 20, 120], [1, 0, 0, 0]], [1.5, [0, 0, 50], [1, 0, 0, 0], 0, 0, 0]];
  PERS wobjdata wTable := [FALSE, TRUE, "", [[0, 0, 0], [1, 0, 0, 0]], [[0, 0, 0], [1, 0, 0, 0]]];
  CONST jointtarget jHome := [[10, -30, 40, 20, 50, -30], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  PERS jointtarget jPark := [[-45.0,-50.0,70.0,-100.0,-60.0,120.0],[0,9E+09,9E+09,9E+09,9E+09,9E+09]];
  LOCAL VAR jointtarget jLocal := [[120, -20, 20, 30, 40, 170],
                                   [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];  ! continued on a second line
  CONST robtarget pApproach := [[231.980,68.259,-325.384],[-0.14399393,0.85724371,0.13836302,-0.47460999],
    [0,0,-1,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  PERS robtarget pPick:=[[146.293,-22.849,-175.265],[-0.52448421,0.66064452,-0.52225936,-0.12534068],[-1,-2,1,1],[250.5,9E+09,9E+09,9E+09,9E+09,9E+09]];
  VAR robtarget pLeave := [[-222.445, 248.694, -354.133], [0.26200263, 0.71984631, -0.60402277, 0.21984631], [1, 0, 1, 0], [9E9, 9E9, 9E9, 9E9, 9E9, 9E9]];
  LOCAL CONST robtarget pPath{2} := [
    [[-123.369,-83.799,-72.453],[0.08682326,0.81528227,0.29209514,-0.49239919],[0,0,-1,6],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
    [[-116.029,32.589,-493.589],[-0.31142689,0.75185102,0.56496683,0.13618301],[-2,0,1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]
  ];
  CONST string sNote := "a string with ! and ; and [ inside";

  PROC main()
    ! MoveAbsJ with the target written inline, as a controller's log writes it
    MoveAbsJ [[0,-40,60,0,45,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]\NoEOffs, v1000, z50, tool0;
    MoveAbsJ jHome, v1000, fine, tool0;
    MoveJ pApproach, v1000, z50, tGripper;
    MoveL [[103.185,-20.000,-229.637],[0,0.84339145,0,-0.53729961],[0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
          v200, fine, tGripper;   ! inline robtarget on a continued line
    MoveL Offs(pPick, 0, 0, 100), v500, z10, tGripper;
    MoveC pPath{1}, pPath{2}, v100, z5, tGripper;
    MoveAbsJ jPark, v1000, fine, tool0; MoveL pLeave, v100, fine, tGripper;
  ENDPROC
ENDMODULE
