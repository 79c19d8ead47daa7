OziExplorer Track Point File Version 2.1
WGS 84
Altitude is in Feet
Reserved 3
0,2,255,t,0,0,2,8421376
1
56.0,37.0,0,3000,1e308,01-Jan-70,00:00:00
