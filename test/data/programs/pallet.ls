/PROG  PALLET
/ATTR
OWNER		= MNEDITOR;
COMMENT		= "example";
PROG_SIZE	= 0;
CREATE		= DATE 25-01-01  TIME 00:00:00;
MODIFIED	= DATE 25-01-01  TIME 00:00:00;
FILE_NAME	= ;
VERSION		= 0;
LINE_COUNT	= 11;
MEMORY_SIZE	= 0;
PROTECT		= READ_WRITE;
TCD:  STACK_SIZE	= 0,
      TASK_PRIORITY	= 50,
      TIME_SLICE	= 0,
      BUSY_LAMP_OFF	= 0,
      ABORT_REQUEST	= 0,
      PAUSE_REQUEST	= 0;
DEFAULT_GROUP	= 1,*,*,*,*;
CONTROL_CODE	= 00000000 00000000;
/MN
   1:  !An example for tolerance-ros ;
   2:  UTOOL_NUM=1 ;
   3:J P[1] 100% FINE    ;
   4:  UFRAME_NUM=1 ;
   5:J P[2] 100% CNT50    ;
   6:L P[3] 500mm/sec FINE    ;
   7:  UFRAME_NUM=0 ;
   8:J P[4] 100% CNT50    ;
   9:J P[5] 100% CNT50    ;
  10:C P[6]    
    :  P[7] 300mm/sec CNT10    ;
  11:J P[8] 50% FINE    ;
/POS
P[1]{
   GP1:
	UF : 0, UT : 1,	
	J1=     0.000 deg,	J2=     0.000 deg,	J3=     0.000 deg,
	J4=     0.000 deg,	J5=   -90.000 deg,	J6=     0.000 deg
};
P[2]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =   -21.825  mm,	Y =   571.071  mm,	Z =   561.725  mm,
	W =   161.876 deg,	P =    18.831 deg,	R =    77.232 deg
};
P[3]{
   GP1:
	UF : 1, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =    78.630  mm,	Y =  -282.761  mm,	Z =   228.224  mm,
	W =  -169.850 deg,	P =    24.421 deg,	R =   -33.029 deg
};
P[4]{
   GP1:
	UF : 0, UT : 1,		CONFIG : 'F U T, 0, 0, 1',
	X =  1886.530  mm,	Y =   324.611  mm,	Z =  -198.324  mm,
	W =  -157.485 deg,	P =     1.043 deg,	R =     4.667 deg
};
P[5]{
   GP1:
	UF : 0, UT : 1,		CONFIG : 'F U B, 0, 0, 0',
	X = -1258.245  mm,	Y =  -902.782  mm,	Z =  1822.767  mm,
	W =   -22.038 deg,	P =    53.864 deg,	R =   129.124 deg
};
P[6]{
   GP1:
	UF : 0, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =  1717.335  mm,	Y =   399.045  mm,	Z =  -176.760  mm,
	W =   173.764 deg,	P =    10.943 deg,	R =    25.864 deg
};
P[7]{
   GP1:
	UF : 0, UT : 1,		CONFIG : 'N U T, 0, 0, 0',
	X =  1679.785  mm,	Y =   559.268  mm,	Z =  -215.582  mm,
	W =   177.417 deg,	P =    15.084 deg,	R =    36.735 deg
};
P[8]{
   GP1:
	UF : 0, UT : 1,	
	J1=    10.000 deg,	J2=   -20.000 deg,	J3=    50.000 deg,
	J4=     0.000 deg,	J5=   -60.000 deg,	J6=     0.000 deg
};
/END
