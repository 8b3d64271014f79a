"""The textbook's gyro instruments (gyrocompass, gyro horizon, directional gyro, stability of tops
and spinning shells): each module holds its dynamics and the closed forms it is checked against."""
