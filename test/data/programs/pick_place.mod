MODULE PickPlace
    ! An example for tolerance-ros filter: the FANUC R-2000iC/165F URDF of the tests stands for the robot.
    ! Its tool points 200 mm along the flange's x axis; the table is a work object.
    PERS tooldata tGripper:=[TRUE,[[200,0,0],[0.707107,0,0.707107,0]],[25,[100,0,0],[1,0,0,0],0,0,0]];
    TASK PERS wobjdata wobjTable:=[FALSE,TRUE,"",[[1800,-400,300],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
    CONST jointtarget jHome:=[[0,0,0,0,-90,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pPick:=[[126.72,557.26,561.72],[0.058013,0.525503,-0.820735,0.216506],[0,0,0,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pPlace:=[[2.77,-293.48,228.22],[0.157253,-0.413295,-0.881662,-0.164716],[-1,-1,-1,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pFlip:=[[1886.53,324.61,471.68],[0.050739,-0.371026,0.907828,0.188716],[0,1,-2,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pBack:=[[-1258.25,-902.78,2492.77],[0.827452,-0.037082,-0.474672,-0.297716],[0,1,-1,4],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    CONST robtarget pUnder:=[[407.06,2757.04,1102.56],[0.507495,-0.794843,-0.235234,0.23524],[0,1,-1,2],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
    PERS robtarget pArc{2}:=[[[1717.33,399.04,493.24],[0.080675,0.227501,-0.967599,0.074078],[0,0,0,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]],
                             [[1679.78,559.27,454.42],[0.117495,0.315115,-0.939672,0.062559],[0,0,0,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]]];

    PROC main()
        MoveAbsJ jHome\NoEOffs, v1000, z50, tool0;
        MoveJ pPick, v1000, z50, tGripper\WObj:=wobjTable;   ! pick
        MoveL pPlace, v500, fine, tGripper\WObj:=wobjTable;
        MoveJ pFlip, v1000, z50, tGripper;
        MoveJ pBack, v1000, z100, tGripper;
        MoveJ pUnder, v1000, z100, tGripper;
        MoveL [[2296.07,0,639.66],[0.087156,0,0.996195,0],[0,0,0,1],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v200, z10, tGripper;
        MoveC pArc{1}, pArc{2}, v200, z10, tGripper;
        MoveAbsJ [[10,-20,30,0,-60,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]], v500, fine, tool0;
    ENDPROC
ENDMODULE
